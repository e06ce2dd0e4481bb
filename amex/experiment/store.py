"""``episodes.csv``: the one place episode results live, appended durably, read verified.

One module on purpose (~450 lines): the file's format, its one writer and its one reader change
together, and the row checks are shared by both.

One row per episode: the metrics (:data:`amex.sim.metrics.COLUMNS`), then

* ``config_hash``, ``scene_hash``, ``code_hash``: which configuration and code computed the row
  (:mod:`amex.experiment.hashes`; a run resumes by skipping the environments recorded under its
  configuration hash);
* ``episodes``: the run's number of environments when the row was written; ``env`` is below it;
* ``row_hash``: a checksum of the row, SHA-256 of the names and values of every column before it
  but the two timing columns (:func:`row_checksum`).

Rows are checked by one reader, :func:`read_episodes`, for the resume (:class:`EpisodeStore`, the
command line's pre-flight :meth:`EpisodeStore.check`) and for ``make table`` alike: every row
whole and parseable, values possible (finite where they must be), its ``row_hash`` matching its
values, one configuration per file (hashes, task, method, seed), one row per environment, ``env``
below ``episodes``. Any problem is one :class:`StoreError` line ``path:line: problem``. The row hash
detects hand edits, damage and hashes copied between rows or files; it is a checksum, not a
signature: whoever recomputes it can forge a row. Files written before row hashes existed still
read, flagged unverified (:attr:`StoredEpisodes.verified`); a run resumes from verified rows only.

Rows are written through :mod:`amex.core.durable`: a row is appended completely and fsynced, or the
file is cut back to its previous length and :class:`~amex.core.durable.WriteError` raised (a full
disk), so a killed or failed run leaves whole rows only and resumes once the cause is gone; a torn
last line (e.g. a power loss) is dropped on read and cut off when a run resumes. A zero-byte file
counts as no rows (a fresh run). A file with rows is never rewritten otherwise: columns amex does
not know (a user's, or a newer version's metric) stay as they are, and rows appended by this
version leave them empty (a column of your own belongs after ``row_hash``, where the checksum does
not reach; one inserted before it makes every row fail its check).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from amex.core.durable import append_durably, refuse_link, replace_durably
from amex.core.errors import StoreError
from amex.experiment.hashes import (
    RunIdentity,
    code_hash,
    config_hash,
    method_code_hash,
    scene_hash,
)
from amex.sim.metrics import COLUMNS, REQUIRED_COLUMNS, TIMING_COLUMNS, EpisodeResult

HASH_COLUMNS = ("config_hash", "scene_hash")
ROW_HASH = "row_hash"
#: Columns after the metrics: the hashes, the run's size and the row's checksum (last).
RECORD_COLUMNS = (*HASH_COLUMNS, "code_hash", "episodes", ROW_HASH)
CSV_COLUMNS = COLUMNS + RECORD_COLUMNS
#: The columns every row of one file shares: one configuration per file.
IDENTITY_COLUMNS = ("task", "method", "seed", "config_hash", "scene_hash", "code_hash")


# ---------------------------------------------------------------------------- values
def format_value(value: object) -> str:
    """CSV text of a metric: ``repr`` of floats (round-trips bit for bit), 0/1 for booleans."""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def _line(values: list[str]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(values)
    return buf.getvalue()


def parse_bool(text: str, name: str = "value") -> bool:
    """A flag as written by :func:`format_value`: exactly ``0`` or ``1``, else ``ValueError``."""
    if text == "1":
        return True
    if text == "0":
        return False
    raise ValueError(f"{name}={text!r}, valid: 0 or 1")


def parse_result(row: dict[str, str]) -> EpisodeResult:
    """An :class:`EpisodeResult` from a csv row (as read by ``csv.DictReader``).

    The one parser of stored values (resume and ``make table`` alike): flags must be 0 or 1,
    integers integers; anything else raises ``ValueError`` naming the column.
    """
    values: dict[str, Any] = {}
    for f in fields(EpisodeResult):
        if f.name not in row and f.name not in REQUIRED_COLUMNS:
            continue  # a metric added after the file was written: its default (nan)
        text = row[f.name]
        if f.type in ("bool", bool):
            values[f.name] = parse_bool(text, f.name)
        elif f.type in ("int", int):
            try:
                values[f.name] = int(text)
            except ValueError:
                raise ValueError(f"{f.name}={text!r}, valid: an integer") from None
        elif f.type in ("float", float):
            try:
                values[f.name] = float(text)
            except ValueError:
                raise ValueError(f"{f.name}={text!r}, valid: a number") from None
        else:
            values[f.name] = text
    return EpisodeResult(**values)


_TIMES = ("compute_time_median", "compute_time_mean")  # NaN when the method never stepped
_MEASURES = ("final_distance", "sum_sq_acc", "sum_sq_acc_paper", "int_sq_acc")
_MEASURED_ALWAYS = ("final_distance", "sum_sq_acc")  # the others are NaN when not computed


def impossible_value(result: EpisodeResult, columns: tuple[str, ...] = COLUMNS) -> str:
    """Why no episode can have produced ``result`` ("" if one can); ``columns``: those stored.

    ``final_time`` is finite and >= 0; compute times are >= 0 or NaN (no step); distances and
    acceleration sums are never negative or -inf; the final distance and ``sum_sq_acc`` are
    finite in a successful episode (only a diverged one, which does not succeed, has NaN or inf
    there), the other sums finite or NaN (not computed); a success has no failure.
    """
    success = result.success or result.success_005
    if result.env < 0:
        return f"env={result.env}, valid: >= 0"
    if not (math.isfinite(result.final_time) and result.final_time >= 0.0):
        return f"final_time={result.final_time!r}, valid: a finite time >= 0"
    for name in _TIMES:
        value = getattr(result, name)
        if not (math.isnan(value) or (math.isfinite(value) and value >= 0.0)):
            return f"{name}={value!r}, valid: a finite time >= 0, or nan"
    for name in _MEASURES:
        value = getattr(result, name)
        if value < 0.0:
            return f"{name}={value!r}, valid: >= 0"
        if success and name in columns and math.isinf(value):
            return f"{name}={value!r} in a successful episode, valid: a finite value"
        if success and name in _MEASURED_ALWAYS and math.isnan(value):
            return f"{name}={value!r} in a successful episode, valid: a finite value"
    if success and result.failure:
        return f"success with failure={result.failure!r}"
    return ""


def row_checksum(header: tuple[str, ...] | list[str], values: list[str]) -> str:
    """The ``row_hash`` of a row: SHA-256 (16 hex) of the names and values before that column.

    The timing columns (:data:`~amex.sim.metrics.TIMING_COLUMNS`, the machine's speed) are left
    out, so two runs of one configuration write the same rows, checksums included, outside
    them; their values are still checked (:func:`impossible_value`), their digits are not.
    """
    k = list(header).index(ROW_HASH)
    kept = [i for i in range(k) if header[i] not in TIMING_COLUMNS]
    names, texts = [header[i] for i in kept], [values[i] for i in kept]
    payload = json.dumps([names, texts], ensure_ascii=False, separators=(",", ":"))
    return hashlib.sha256(payload.encode()).hexdigest()[:16]


# ---------------------------------------------------------------------------- the one reader
@dataclass(frozen=True)
class StoredEpisodes:
    """The rows of one episodes.csv, every one checked (:func:`read_episodes`).

    Attributes:
        path: the file.
        header: its columns, those amex does not know included.
        rows: each row as a dict of the column texts, in file order.
        results: each row's values, typed, in file order.
        verified: every row carries a ``row_hash`` matching its values (True for no rows); False
            for a file written before row hashes existed (read, but nothing vouches for it).
        complete_size: bytes of the file up to its last complete line (a torn tail after).
    """

    path: Path
    header: tuple[str, ...]
    rows: list[dict[str, str]]
    results: list[EpisodeResult]
    verified: bool
    complete_size: int

    @property
    def by_env(self) -> dict[int, EpisodeResult]:
        """The results by environment."""
        return {r.env: r for r in self.results}


class _Reader:
    """The checks of one file on its own, row by row (:func:`read_episodes`)."""

    def __init__(self, path: Path, header: tuple[str, ...]) -> None:
        self.path, self.header = path, header
        self.first: dict[str, tuple[str, int]] = {}  # identity column -> (value, line)
        self.envs: dict[int, int] = {}  # env -> line
        self.unhashed: list[int] = []  # lines of rows without a row hash
        self.hashed = 0  # rows with one

    def fail(self, line: int, problem: str) -> StoreError:
        return StoreError(f"{self.path}:{line}: {problem}")

    def check(self, line: int, values: list[str]) -> tuple[dict[str, str], EpisodeResult]:
        if len(values) != len(self.header):
            raise self.fail(line, f"{len(values)} fields, expected {len(self.header)}")
        row = dict(zip(self.header, values, strict=True))
        try:
            result = parse_result(row)
        except (KeyError, ValueError) as e:
            raise self.fail(line, f"malformed row ({e})") from e
        problem = impossible_value(result, self.header)
        if problem:
            raise self.fail(line, f"impossible value: {problem}")
        self._check_hash(line, row, values)
        self._check_identity(line, row)
        self._check_env(line, row, result.env)
        return row, result

    def _check_hash(self, line: int, row: dict[str, str], values: list[str]) -> None:
        stated = row.get(ROW_HASH, "")
        if not stated:
            if self.hashed:
                raise self.fail(line, "row_hash is empty where the rows before carry one")
            self.unhashed.append(line)
            return
        if stated != row_checksum(self.header, values):
            raise self.fail(
                line,
                f"row_hash {stated} does not match the row's values (edited or damaged after "
                "it was written, or a hash copied from another row)",
            )
        self.hashed += 1

    def _check_identity(self, line: int, row: dict[str, str]) -> None:
        for name in IDENTITY_COLUMNS:
            if name in row:
                value = row[name]
                first = self.first.setdefault(name, (value, line))
                if value != first[0]:
                    raise self.fail(
                        line,
                        f"rows of two configurations in one file: {name}={value} here, "
                        f"{first[0]} on line {first[1]}",
                    )

    def _check_env(self, line: int, row: dict[str, str], env: int) -> None:
        if env in self.envs:
            raise self.fail(
                line, f"env {env} recorded twice (first on line {self.envs[env]}); one row each"
            )
        self.envs[env] = line
        text = row.get("episodes", "")
        if text:
            try:
                episodes = int(text)
            except ValueError:
                problem = f"malformed row (episodes={text!r}, valid: an integer)"
                raise self.fail(line, problem) from None
            if env >= episodes:
                raise self.fail(line, f"env={env} beyond the run's {episodes} episodes")

    def check_expected(self, expect: RunIdentity) -> None:
        """After every row passed: the file's one configuration must be ``expect``'s."""
        where = "choose another hydra.run.dir (hydra.sweep.dir for -m)"
        if not self.envs:
            return
        found = {name: value for name, (value, _) in self.first.items()}
        line = min(self.envs.values())
        if expect.config_hash and found.get("config_hash", "") != expect.config_hash:
            now = expect.code_hash or method_code_hash(found.get("method", ""))
            recorded = found.get("code_hash", "")
            if recorded and recorded != now:
                raise self.fail(
                    line,
                    f"episodes computed by other code (code hash {recorded}, this code {now}: "
                    f"amex, its numerical packages or method {found.get('method')}'s module "
                    f"changed since); a resume would mix two versions of the code: {where}",
                )
            raise self.fail(
                line,
                f"episodes of another configuration (hash {found.get('config_hash') or 'none'}, "
                f"this run {expect.config_hash}); {where}",
            )
        for name in IDENTITY_COLUMNS:
            wanted = getattr(expect, name)
            if wanted not in (None, "") and found.get(name) != str(wanted):
                raise self.fail(line, f"{name}={found.get(name)}, this run's {name} is {wanted}")
        if self.unhashed:
            raise self.fail(
                self.unhashed[0],
                "no row_hash: the row cannot be verified, and a run resumes from verified rows "
                f"only; {where}",
            )


def read_episodes(path: Path, expect: RunIdentity | None = None) -> StoredEpisodes:
    """Every row of the episodes.csv ``path``, checked (module notes); a torn last line dropped.

    Args:
        path: the file; a zero-byte file has no rows.
        expect: what a resuming run requires of every row (its configuration hash, ...); rows
            without a row hash are then refused too. None: one configuration, whichever.

    Raises:
        StoreError: the file cannot be read, is not an amex episodes.csv, or a row fails a check;
            one line ``path:line: problem``.
    """
    try:
        data = path.read_bytes()
    except OSError as e:
        raise StoreError(f"{path}: cannot read ({e.strerror or e})") from e
    complete = data[: data.rfind(b"\n") + 1]  # a last line without its newline is torn
    if not data:
        return StoredEpisodes(path, (), [], [], True, 0)
    try:
        text = complete.decode("utf-8")
    except UnicodeDecodeError as e:
        raise StoreError(f"{path}: cannot read (not text)") from e
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        header = tuple(next(reader))
    except StopIteration:
        raise StoreError(f"{path}: no header line") from None
    except csv.Error as e:
        raise StoreError(f"{path}:1: not an amex episodes.csv ({e})") from e
    if header[: len(REQUIRED_COLUMNS)] != REQUIRED_COLUMNS:
        raise StoreError(f"{path}: not an amex episodes.csv (header {','.join(header[:4])}...)")
    twice = sorted({c for c in header if header.count(c) > 1})
    if twice:
        raise StoreError(f"{path}:1: column {twice[0]} twice in the header")
    check = _Reader(path, header)
    rows, results = [], []
    line = reader.line_num + 1
    while True:
        try:
            values = next(reader)
        except StopIteration:
            break
        except csv.Error as e:
            raise StoreError(f"{path}:{line}: malformed row ({e})") from e
        row, result = check.check(line, values)
        rows.append(row)
        results.append(result)
        line = reader.line_num + 1
    if expect is not None:
        check.check_expected(expect)
    verified = ROW_HASH in header and not check.unhashed
    return StoredEpisodes(path, header, rows, results, verified, len(complete))


def read_rows(path: Path) -> list[dict[str, str]]:
    """The rows of an episodes.csv as dicts of column texts, each checked (:func:`read_episodes`).

    Raises:
        StoreError: a missing file, a foreign header or any row that fails a check.
    """
    return read_episodes(path).rows


# ---------------------------------------------------------------------------- the writer
class EpisodeStore:
    """Append-only episodes.csv of one run directory, resumable by config hash.

    Opening it checks the rows already there (:func:`read_episodes` with the run's identity) and
    writes nothing but a header into a file without rows (this version's columns, then any others
    its header named), or cuts a torn last line off; rows are appended in the file's own columns
    (module notes).

    Args:
        path: the csv file (not a symbolic link).
        config_hash: hash of the run's configuration.
        scene_hash: hash of its scenes.
        identity: everything the rows must carry (:meth:`for_config` fills it); default: the
            two hashes only.

    Raises:
        StoreError: a row already there fails a check or belongs to another configuration.
        WriteError: the file is a symbolic link or cannot be written.
    """

    def __init__(
        self, path: Path, config_hash: str, scene_hash: str, identity: RunIdentity | None = None
    ) -> None:
        self.path = path
        self.identity = identity or RunIdentity(config_hash, scene_hash)
        self.config_hash = config_hash
        self.scene_hash = scene_hash
        self.header = CSV_COLUMNS
        self.done: dict[int, EpisodeResult] = {}
        refuse_link(path)
        stored = read_episodes(path, self.identity) if path.exists() else None
        if stored is None or not stored.rows:  # nothing to keep but the names of unknown columns
            unknown = [c for c in (stored.header if stored else ()) if c not in CSV_COLUMNS]
            self.header = (*CSV_COLUMNS, *unknown)
            replace_durably(path, _line(list(self.header)).encode())
            return
        self.header = stored.header
        self.done = stored.by_env
        data = path.read_bytes()
        if len(data) > stored.complete_size:  # a torn last line: cut off, nothing else changes
            replace_durably(path, data[: stored.complete_size])

    @classmethod
    def for_config(cls, path: Path, config: Any) -> EpisodeStore:
        """The store of a run of ``config`` (a :class:`~amex.experiment.config.RunConfig`)."""
        identity = RunIdentity.of(config)
        return cls(path, identity.config_hash, identity.scene_hash, identity)

    @staticmethod
    def check(path: Path, config_hash: str) -> list[dict[str, str]]:
        """The rows of ``path``; :class:`StoreError` if any fails a check or has another hash."""
        return read_episodes(path, RunIdentity(config_hash)).rows

    def append(self, result: EpisodeResult) -> None:
        """Record ``result`` durably: the whole row, fsynced, or :class:`WriteError` and no row.

        Raises:
            StoreError: ``result`` could not be read back (its env is recorded, or a value is
                impossible); nothing is written.
        """
        if result.env in self.done:
            raise StoreError(f"{self.path}: env {result.env} is recorded already")
        problem = impossible_value(result)
        if problem:
            raise StoreError(f"{self.path}: env {result.env} not recorded: {problem}")
        known = {k: format_value(v) for k, v in result.as_row().items()}
        identity = self.identity
        known.update(
            config_hash=self.config_hash,
            scene_hash=self.scene_hash,
            code_hash=identity.code_hash,
            episodes="" if identity.episodes is None else str(identity.episodes),
        )
        values = [known.get(column, "") for column in self.header]
        if ROW_HASH in self.header:
            values[self.header.index(ROW_HASH)] = row_checksum(self.header, values)
        append_durably(self.path, _line(values).encode())
        self.done[result.env] = result


__all__ = [
    "CSV_COLUMNS",
    "HASH_COLUMNS",
    "EpisodeStore",
    "RunIdentity",
    "StoredEpisodes",
    "code_hash",
    "config_hash",
    "read_episodes",
    "read_rows",
    "parse_result",
    "scene_hash",
]
