"""The fuzz engine: run generated calls of the public API and sort each outcome (docs/fuzz.md).

An entry point is a function ``make(rng) -> Case``: one generated call and its oracle. The engine runs the
call under a per-call time limit, records warnings, and sorts the outcome:

- ``ok``: it returned and the oracle (a round trip or an independent formula) holds;
- ``typed``: it raised a :class:`carmkin.CarmkinError` (fine for junk, and for degenerate-but-valid input:
  "right or refused");
- ``untyped``: any other exception (a bare TypeError, LinAlgError, cv2.error, ...);
- ``wrong``: it returned for junk input, or its answer fails the oracle (a silent wrong answer);
- ``hang``: it ran past :data:`CALL_LIMIT_S`;
and, independently, ``warnings``: the call let a warning escape.

About a third of the cases replace one argument by junk (:func:`junk`): None, a dict, a string, bytes, a
complex number, a bool, or an array of strings / complex / bools / NaN. Numpy only on import; the entry
points live in ``fuzz_entries*.py``.
"""

from __future__ import annotations

import math
import signal
import traceback
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

import carmkin

#: A call running longer than this (s) is a hang (a guard against unbounded work, not a timing assertion).
CALL_LIMIT_S = 20
#: Fraction of the cases whose one argument is replaced by junk.
JUNK_FRACTION = 0.3
#: Outcome columns of the table, in order.
OUTCOMES = ("ok", "typed", "untyped", "wrong", "hang")


@dataclass
class Case:
    """One generated call: ``fn(*args, **kwargs)``; ``check(result) -> bool`` is the oracle for valid input;
    ``junk`` names the argument replaced by junk (the call must then raise a typed error); ``named``: a word
    that typed error's message must contain (the argument's name), else the case is untyped."""

    fn: Callable
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)
    check: Callable[[Any], bool] | None = None
    junk: str | None = None
    named: str | None = None


@dataclass
class Tally:
    cases: int = 0
    counts: dict = field(default_factory=lambda: dict.fromkeys(OUTCOMES, 0))
    warned: int = 0
    examples: list = field(default_factory=list)


# --- junk ---------------------------------------------------------------------------------------------
JUNK_TYPES = (None, {"a": 1}, "1.5", b"1.5", 1 + 1j, True, object())


def junk(rng: np.random.Generator, like=None):
    """A junk value: one of :data:`JUNK_TYPES`, or ``like`` (an array) as strings, complex, bools, or NaN."""
    k = int(rng.integers(0, len(JUNK_TYPES) + 4))
    if k < len(JUNK_TYPES) or like is None:
        return JUNK_TYPES[k % len(JUNK_TYPES)]
    a = np.array(like, dtype=float)
    if k == len(JUNK_TYPES):
        return a.astype(str)
    if k == len(JUNK_TYPES) + 1:
        return a.astype(complex) + 1e-3j
    if k == len(JUNK_TYPES) + 2:
        return a.astype(bool)
    a = a.copy()
    if a.size:
        a.flat[int(rng.integers(0, a.size))] = rng.choice([np.nan, np.inf, -np.inf])
        return a
    return None


def maybe_junk(rng: np.random.Generator, case: Case, names: tuple[str, ...]) -> Case:
    """With probability :data:`JUNK_FRACTION`, replace one positional argument (named ``names[i]``) by junk."""
    if not names or rng.random() >= JUNK_FRACTION:
        return case
    i = int(rng.integers(0, len(names)))
    args = list(case.args)
    value = None
    while value is None:  # a name ending in "?" takes None as its default: draw other junk for it
        value = junk(rng, args[i] if isinstance(args[i], (np.ndarray, list, tuple)) else None)
        if not names[i].endswith("?"):
            break
    args[i] = value
    return Case(case.fn, tuple(args), case.kwargs, None, names[i].rstrip("?"))


# --- running --------------------------------------------------------------------------------------------
class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang


def run_case(case: Case) -> tuple[str, bool, str]:
    """``(outcome, warned, detail)`` of one case."""
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, CALL_LIMIT_S)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = case.fn(*case.args, **case.kwargs)
        except _Hang:
            outcome, detail = "hang", f"ran past {CALL_LIMIT_S} s"
        except carmkin.CarmkinError as exc:
            outcome, detail = ("typed", "") if str(exc) else ("untyped", "a typed error without a message")
            if outcome == "typed" and case.named and case.named not in str(exc):
                outcome, detail = "untyped", f"a typed error that does not name {case.named}: {exc}"
        except Exception as exc:  # noqa: BLE001 - every other exception is a finding
            frame = traceback.extract_tb(exc.__traceback__)[-1]
            outcome, detail = "untyped", f"{type(exc).__name__}: {exc} ({frame.filename}:{frame.lineno})"
        else:
            if case.junk is not None:
                outcome, detail = "wrong", f"accepted junk for {case.junk}"
            else:
                try:
                    good = bool(case.check(result)) if case.check is not None else True
                except Exception as exc:  # noqa: BLE001 - an answer the oracle cannot read is wrong
                    good, detail = False, f"oracle could not read the answer: {type(exc).__name__}: {exc}"
                else:
                    detail = "" if good else "oracle failed"
                outcome = "ok" if good else "wrong"
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old)
    warned = bool(caught)
    if warned and not detail:
        detail = f"warning: {caught[0].category.__name__}: {caught[0].message}"
    return outcome, warned, detail


def run(entries: dict, cases: int, seed: int = 0, examples: int = 3) -> dict[str, Tally]:
    """Run ``cases`` cases spread over ``entries`` by their weights; a :class:`Tally` per entry point.

    ``entries`` maps a name to ``(make, weight)``; each entry gets ``cases · weight / Σ weights`` cases (at
    least one). The cases of entry ``k`` are drawn from ``default_rng((seed, k))``: reproducible.
    """
    total = sum(w for _, w in entries.values())
    out = {}
    for k, (name, (make, weight)) in enumerate(entries.items()):
        rng = np.random.default_rng((seed, k))
        tally = Tally()
        for _ in range(max(1, math.ceil(cases * weight / total))):
            case = make(rng)
            outcome, warned, detail = run_case(case)
            tally.cases += 1
            tally.counts[outcome] += 1
            tally.warned += warned
            if (outcome in ("untyped", "wrong", "hang") or warned) and len(tally.examples) < examples:
                tally.examples.append(f"{outcome}{' +warning' if warned else ''}: {detail} "
                                      f"[junk={case.junk}, args={_short(case.args)}]")
        out[name] = tally
    return out


def _short(args) -> str:
    text = repr(args).replace("\n", " ")
    return text if len(text) < 160 else text[:157] + "..."


def table(tallies: dict[str, Tally]) -> str:
    """The outcome table (Markdown), one row per entry point and a total."""
    head = "| entry point | cases | ok | typed error | untyped | silent wrong | warnings | hangs |"
    lines = [head, "|" + "---|" * 8]
    total = Tally()
    for name, t in tallies.items():
        c = t.counts
        lines.append(f"| `{name}` | {t.cases} | {c['ok']} | {c['typed']} | {c['untyped']} | {c['wrong']} | "
                     f"{t.warned} | {c['hang']} |")
        total.cases += t.cases
        total.warned += t.warned
        for key in OUTCOMES:
            total.counts[key] += c[key]
    c = total.counts
    lines.append(f"| **total** | {total.cases} | {c['ok']} | {c['typed']} | {c['untyped']} | {c['wrong']} | "
                 f"{total.warned} | {c['hang']} |")
    return "\n".join(lines)


def findings(tally: Tally) -> int:
    """Cases of one entry point that are findings: untyped, silent wrong, hang, or a leaked warning."""
    return tally.counts["untyped"] + tally.counts["wrong"] + tally.counts["hang"] + tally.warned
