"""My methods for amex."""
