"""``amex-live``: one episode at a time in real time, in the browser (viser).

:mod:`~amex.app.live.session` runs the episodes (the ordinary loop with a live scene and a pacing
recorder, :mod:`amex.sim.live`), :mod:`~amex.app.live.page` is the page, :mod:`~amex.app.live.cli`
the command line. See ``docs/live.md``.
"""
