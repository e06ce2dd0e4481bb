"""The version of amex, in one place (pyproject.toml, amex.__version__, --version read it)."""

__version__ = "0.2.0"
