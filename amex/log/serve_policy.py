"""Who ``amex-log view`` answers: loopback hosts, the Host header, allowed origins, byte ranges."""

from __future__ import annotations

import ipaddress
import re
from dataclasses import dataclass
from http import HTTPStatus

from amex.log.serve_files import Refused

FOXGLOVE_ORIGIN = "https://app.foxglove.dev"
RANGE = re.compile(r"bytes=(\d{0,18})-(\d{0,18})")


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a name or an address) is this machine's loopback interface only."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def split_host(value: str) -> tuple[str, int] | None:
    """``(host, port)`` of a ``Host`` header value (port 80 if none); None if malformed."""
    value = value.strip().lower()
    if value.startswith("["):
        host, bracket, rest = value.partition("]")
        host += bracket
    else:
        host, _, port = value.partition(":")
        rest = ":" + port if port or value.endswith(":") else ""
    if not rest:
        return (host, 80) if host else None
    if not (rest.startswith(":") and rest[1:].isdigit() and len(rest) <= 6):
        return None
    return host, int(rest[1:])


@dataclass(frozen=True)
class Policy:
    """Which ``Host`` names and which browser origins this server answers."""

    port: int
    names: frozenset[str]  # lower case, IPv6 addresses in brackets
    any_address: bool = False  # exposed on the network: an IP address names this host too

    def host_ok(self, value: str) -> bool:
        """Whether a ``Host`` header names this server (its name or address, and its port)."""
        split = split_host(value)
        if split is None or split[1] != self.port:
            return False
        if split[0] in self.names:
            return True
        return self.any_address and split[0] != "" and is_address(split[0])

    def origin_ok(self, origin: str) -> bool:
        """Whether a page of ``origin`` may read what this server serves."""
        if origin == FOXGLOVE_ORIGIN:
            return True
        return origin.startswith("http://") and "/" not in origin[7:] and self.host_ok(origin[7:])


def is_address(host: str) -> bool:
    """Whether ``host`` is an IP address (bracketed IPv6 included), not a name."""
    try:
        ipaddress.ip_address(host.strip("[]"))
    except ValueError:
        return False
    return True


def byte_range(header: str, size: int) -> tuple[int, int]:
    """``(first, last)`` byte of a ``Range`` header (one range) of a ``size``-byte answer.

    Raises:
        Refused: 416 for a malformed, multiple, absurd or unsatisfiable range.
    """
    m = RANGE.fullmatch(header.strip())
    if m is None or not (m.group(1) or m.group(2)):
        raise Refused(
            HTTPStatus.REQUESTED_RANGE_NOT_SATISFIABLE,
            "Range: only one range bytes=FIRST-[LAST] or bytes=-SUFFIX, at most 18 digits each",
            size,
        )
    if m.group(1):
        start = int(m.group(1))
        end = min(int(m.group(2)), size - 1) if m.group(2) else size - 1
    else:  # the last n bytes
        start, end = max(size - int(m.group(2)), 0), size - 1
        if int(m.group(2)) == 0:
            start = size
    if start >= size or start > end:
        raise Refused(HTTPStatus.REQUESTED_RANGE_NOT_SATISFIABLE, "range outside", size)
    return start, end
