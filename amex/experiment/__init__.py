"""Experiments: the run configuration, runs of episodes, the ``episodes.csv`` store and shards.

The configuration is checked and converted here, once; no Hydra: scripts call these directly.
"""
