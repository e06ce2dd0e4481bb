"""Command-line parsing for amex's small tools: a usage error is one line and exit code 2.

argparse prints the whole usage block before its error; the project's rule for bad input is one
line on stderr naming the bad value (argparse's message does) and exit code 2.
"""

from __future__ import annotations

import argparse
import sys
from typing import NoReturn


def fail(prog: str, message: str) -> NoReturn:
    """Write ``<prog>: error: <message>`` as one line on stderr and exit with code 2."""
    sys.stderr.write(f"{prog}: error: {' '.join(message.split())}\n")
    raise SystemExit(2)


class OneLineParser(argparse.ArgumentParser):
    """:class:`argparse.ArgumentParser` whose usage errors are one line (see the module notes)."""

    def error(self, message: str) -> NoReturn:
        """Report ``message`` with a pointer to ``--help``; exit code 2."""
        fail(self.prog, f"{message} (see `{self.prog} --help`)")
