"""``hydra/sweeper=amex``: amex-run's sweeper (:mod:`amex.sweeps`), a Hydra plugin."""
