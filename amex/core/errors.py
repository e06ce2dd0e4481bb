"""The one exception hierarchy of amex.

Every error a user can cause or a run can hit derives from :class:`AmexError`, so the CLI can turn
it into a single line on stderr (exit code 2) and an episode can record it as its failure reason.
"""

from __future__ import annotations

from collections.abc import Iterable


class AmexError(Exception):
    """Base class of all amex errors."""


class ConfigError(AmexError):
    """A configuration value is invalid; the message names the value and the valid choices."""

    @classmethod
    def invalid(cls, key: str, value: object, valid: str | Iterable[object]) -> ConfigError:
        """Build the standard message ``invalid <key>=<value>; valid: <choices>``."""
        choices = valid if isinstance(valid, str) else ", ".join(str(v) for v in valid)
        if isinstance(value, (list, tuple)):  # numpy scalars print as np.float64(...)
            value = [v.item() if hasattr(v, "item") else v for v in value]
        return cls(f"invalid {key}={value!r}; valid: {choices}")


class InputError(AmexError):
    """A function got input it cannot use (e.g. a non-finite number); nothing was changed."""


class SolverError(AmexError):
    """A numerical solve failed; ``problem`` carries what was being solved for inspection."""

    def __init__(self, message: str, problem: object = None) -> None:
        super().__init__(message)
        self.problem = problem


class SimulationError(AmexError):
    """The simulation produced non-finite values or diverged; ``reason`` is a short tag."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason
