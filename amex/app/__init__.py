"""The command-line application: ``amex-run``, ``amex-log``, sweeps, progress, ``make bench``.

The only package that imports Hydra or OmegaConf.
"""
