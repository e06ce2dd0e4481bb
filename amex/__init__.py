"""amex: Adaptive Motion Execution (Englert & Toussaint, IROS 2014) and its benchmark."""

__version__ = "0.2.0"
