"""The one exception hierarchy of amex, in one module.

Every error a user can cause or a run can hit is an :class:`AmexError`, so the command-line
tools turn it into a single line on stderr (exit code 2) and an episode records it as its failure
reason. Two ways of stopping are deliberately not errors (they derive from ``BaseException`` so
that no ``except Exception`` swallows them): :class:`Interrupted`, a stop signal, and
:class:`JobFailed`, which carries a job's :class:`AmexError` past Hydra's job runner (which would
otherwise log it as a traceback) to the process that prints it.
"""

from __future__ import annotations

import signal
from collections.abc import Iterable
from pathlib import Path


class AmexError(Exception):
    """Base class of all amex errors; the message is the one line shown to a user."""


# ---------------------------------------------------------------------------- configuration
class ConfigError(AmexError):
    """A configuration value is invalid; the message names the value and the valid choices."""

    @classmethod
    def invalid(cls, key: str, value: object, valid: str | Iterable[object]) -> ConfigError:
        """Build the standard message ``invalid <key>=<value>; valid: <choices>``."""
        choices = valid if isinstance(valid, str) else ", ".join(str(v) for v in valid)
        if isinstance(value, (list, tuple)):  # numpy scalars print as np.float64(...)
            value = [v.item() if hasattr(v, "item") else v for v in value]
        return cls(f"invalid {key}={value!r}; valid: {choices}")


class UsageError(AmexError):
    """A command line that cannot be run (an override, a flag); the message is the one line."""


class LaunchError(UsageError):
    """A sweep or run cannot be launched (launcher options, output directory, lock)."""


# ---------------------------------------------------------------------------- numerics
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


# ---------------------------------------------------------------------------- files and runs
class WriteError(AmexError):
    """A file could not be written completely; the message names the file and the reason."""

    def __init__(self, path: Path | str, reason: str) -> None:
        super().__init__(f"cannot write {path}: {reason}")
        self.path = Path(path)
        self.reason = reason


class LockedError(AmexError):
    """Another process holds the run directory's lock."""


class StoreError(AmexError):
    """An episodes.csv cannot be used; the message names the file."""


class ShardError(AmexError):
    """The shards of a configuration overlap or leave gaps; the message names them."""


# ---------------------------------------------------------------------------- logs
class LogError(AmexError):
    """A log file cannot be read or written; the message names the file and the problem."""


class LogNotFoundError(LogError):
    """The log file does not exist."""


class EmptyLogError(LogError):
    """The log file has no bytes."""


class NotMcapError(LogError):
    """The file is not an MCAP file (wrong magic bytes)."""


class TruncatedLogError(LogError):
    """The file was cut before any message could be recovered."""


class CorruptLogError(LogError):
    """The file is complete but damaged so that no message can be read."""


class LogExistsError(LogError):
    """Refusing to overwrite an existing file."""


class RenderError(LogError):
    """Nothing can be rendered here (no headless OpenGL), or the robot cannot be compiled."""


# ---------------------------------------------------------------------------- stops, not errors
class Interrupted(KeyboardInterrupt):
    """A stop signal arrived; ``signum`` says which (exit code ``128 + signum``)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    def __reduce__(self) -> tuple:
        """Picklable, so a sweep worker can send it back to the launching process."""
        return (Interrupted, (self.signum,))


def stop_behind(error: BaseException) -> BaseException | None:
    """The stop that ``error`` was raised from, if any.

    A stop is a :class:`KeyboardInterrupt` (such as :class:`Interrupted`) or a ``SystemExit``
    raised by a signal handler (submitit's requeue). A stop whose handler ran while a compiled
    function was returning (Numba's boxing of its results can run Python code, a garbage
    collection) reaches Python as a ``SystemError`` ("returned a result with an exception set")
    caused by it; ``amex.app.processes.signals_raise`` and the episode's method step re-raise
    the stop itself.
    """
    seen: set[int] = set()
    cause: BaseException | None = error
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt | SystemExit):
            return cause
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return None


class JobFailed(BaseException):
    """A job stopped with an :class:`AmexError`, carried past Hydra's job runner (module notes).

    Attributes:
        error: the error; its message is the line the launching process prints.
        resumable: whether the closing line should say that the same command resumes.
    """

    def __init__(self, error: AmexError | str, resumable: bool = False) -> None:
        error = error if isinstance(error, AmexError) else AmexError(error)
        super().__init__(error, resumable)
        self.error = error
        self.resumable = resumable

    @property
    def message(self) -> str:
        """The error's one line."""
        return str(self.error)
