"""``hydra/sweeper=amex``: amex-run's sweeper (:mod:`amex.app.sweeps`), a Hydra plugin."""
