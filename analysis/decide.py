"""From tests to verdicts: holds, fails or inconclusive, under one multiple-testing policy.

A claim (one of the paper's five, or "reproduces the paper" over the 12 cells) is a conjunction
of tests, a :class:`Evidence` per task and method or method pair. Each test says which side its
estimate lies on (supports the claim or contradicts it) and with what p-value. With m tests in
the claim over all tasks:

* a task **holds** when each of its tests supports the claim at p < :data:`ALPHA`; the claim
  holds when every task holds (an intersection-union test: level ALPHA without adjustment);
* a task **fails** when one of its tests contradicts the claim at p < ALPHA / m (Bonferroni over
  the claim's m tests: a true claim is called failed with probability at most ALPHA); the claim
  fails when a task fails;
* otherwise **inconclusive at this n**, with the test that left it open.

The five claims and the benchmarks are separate questions: no adjustment across them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import NamedTuple

from .inference import ALPHA

HOLDS, FAILS, OPEN = "holds", "fails", "inconclusive"


class Evidence(NamedTuple):
    """One test of a claim: ``supports`` is the side of the estimate, ``p`` its test's p."""

    supports: bool
    p: float
    text: str  # the estimate, its interval and p, as the tables show them


class Verdict(NamedTuple):
    """A verdict word and the number that decided it."""

    word: str
    evidence: str

    def cell(self) -> str:
        """``holds (T3: 0.93 [0.89, 0.96])`` as a table cell."""
        return f"{self.word} ({self.evidence})" if self.evidence else self.word


class Claim(NamedTuple):
    """A claim judged on every task: the overall verdict and one per task."""

    name: str
    overall: Verdict
    tasks: dict[int, Verdict]


def fmt_p(p: float) -> str:
    """A p-value in two digits (``< 1e-4`` below the bootstrap's resolution)."""
    return "p < 1e-4" if p < 1e-4 else f"p {p:.2g}"


def _task(tests: Sequence[Evidence], fail_level: float) -> tuple[str, Evidence | None]:
    if not tests:
        return OPEN, None
    against = [t for t in tests if not t.supports and t.p < fail_level]
    if against:
        return FAILS, min(against, key=lambda t: t.p)
    weak = [t for t in tests if not (t.supports and t.p < ALPHA)]
    if not weak:
        return HOLDS, max(tests, key=lambda t: t.p)
    return OPEN, max(weak, key=lambda t: (not t.supports, t.p))


def _task_label(task: int) -> str:
    return f"T{task}"


def decide(
    name: str,
    tests: Mapping[int, Sequence[Evidence]],
    too_few: str = "",
    label: Callable[[int], str] = _task_label,
) -> Claim:
    """The verdicts of claim ``name`` from its tests per task (module notes).

    ``too_few``: when not empty, every verdict is inconclusive with this reason (too few
    environments to trust the intervals). ``label``: how the overall evidence names a task.
    """
    if not tests or not any(tests.values()):
        return Claim(name, Verdict("n/a", "no task has the methods it needs"), {})
    m = sum(len(t) for t in tests.values())
    per_task: dict[int, Verdict] = {}
    decided: dict[int, tuple[str, Evidence | None]] = {}
    for task, task_tests in tests.items():
        word, test = _task(task_tests, ALPHA / m)
        if too_few:
            word = OPEN
        decided[task] = (word, test)
        per_task[task] = Verdict(word, test.text if test else "no environment all ran")
    words = [w for w, _ in decided.values()]
    if too_few:
        return Claim(name, Verdict(OPEN, too_few), per_task)
    if FAILS in words:
        task, (_, test) = next((k, v) for k, v in decided.items() if v[0] == FAILS)
        overall = Verdict(FAILS, f"{label(task)}: {test.text}" if test else label(task))
    elif all(w == HOLDS for w in words):
        task = max(decided, key=lambda k: decided[k][1].p if decided[k][1] else 0.0)
        test = decided[task][1]
        overall = Verdict(HOLDS, f"weakest {label(task)}: {test.text}" if test else "")
    else:
        task = next(k for k, v in decided.items() if v[0] == OPEN)
        test = decided[task][1]
        overall = Verdict(OPEN, f"{label(task)}: {test.text}" if test else label(task))
    return Claim(name, overall, per_task)
