"""The authors' implementations of AMEX, the DMP and CR (``implementation=original``).

As their harness ran them (``share/examples/Motion`` of PO-LGP at commit b475fa1fe).
"""
