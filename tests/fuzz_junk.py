"""Junk of every Python type for every public argument (issue 31): a catalogue of values that are wrong for an
argument of a given kind, and a generator that replaces one argument of a valid call by one of them.

Kinds (what the argument is): ``count`` (an integer, e.g. a number of tasks or views), ``real`` (one real
number: a length, an angle, a scale), ``vector:N`` (N real numbers), ``name`` (one of a few strings),
``flag`` (True or False), ``system`` (a :class:`carmkin.CArmSystem`), ``rng`` (a numpy Generator), ``model``
(an object of one dataclass). For each kind :func:`wrong_for` lists values that no reading of the argument's
documentation accepts: None (unless optional), booleans as numbers, strings and bytes (never parsed),
0-d / 1-d / 2-d arrays of strings, objects or the wrong length, NaN and ±inf, complex numbers, dicts,
``object()``, floats as counts, negative and huge values. The oracle of such a call is written here, not in
the code under test: it must raise a :class:`carmkin.CarmkinError` whose message names the argument
(:attr:`fuzz_engine.Case.named`); returning anything, or any other exception, is a finding.
"""

from __future__ import annotations

import numpy as np

from fuzz_engine import Case

#: Junk of every Python type, wrong for an argument of any kind.
ANY = (
    ("dict", lambda: {"a": 1}), ("object", object), ("bytes", lambda: b"1"), ("complex", lambda: 1 + 1j),
    ("type", lambda: float), ("function", lambda: (lambda: 1)), ("set", lambda: {1.0}),
    ("object array", lambda: np.array(["x", 1.0], dtype=object)),
)
#: Junk for a number (a count or a real): None, booleans, strings (plain, 0-d and 1-d string arrays), NaN,
#: ±inf, huge magnitudes, a 1-d array, a 2-d array, an empty list.
NUMBER = (
    ("None", lambda: None), ("True", lambda: True), ("np.True_", lambda: np.True_), ("str", lambda: "2"),
    ("0-d str array", lambda: np.array("2")), ("1-d str array", lambda: np.array(["2"])),
    ("nan", lambda: float("nan")), ("inf", lambda: float("inf")), ("-inf", lambda: float("-inf")),
    ("1e300", lambda: 1e300), ("-1e300", lambda: -1e300), ("1-d array", lambda: np.array([2.0, 3.0])),
    ("2-d array", lambda: np.ones((2, 2))), ("empty list", lambda: []), ("complex 0j", lambda: 2 + 0j),
)
#: Extra junk for a count: a float (never truncated), a float with an integer value, a 0-d array, negative.
COUNT = (("2.5", lambda: 2.5), ("2.0", lambda: 2.0), ("np.float64(2)", lambda: np.float64(2.0)),
         ("0-d float array", lambda: np.array(2.0)), ("-1", lambda: -1), ("10**30", lambda: 10 ** 30),
         ("1-element list", lambda: [2]))
#: Junk for one of a few names.
NAME = (("None", lambda: None), ("int", lambda: 3), ("float", lambda: 1.5), ("True", lambda: True),
        ("unknown name", lambda: "no-such-name"), ("empty", lambda: ""), ("list", lambda: ["x"]),
        ("0-d str array", lambda: np.array("x")), ("nan", lambda: float("nan")))
#: Junk for a flag: anything but True/False (a string "False" would read as True).
FLAG = (("None", lambda: None), ("str False", lambda: "False"), ("str", lambda: "yes"), ("2", lambda: 2),
        ("float", lambda: 0.5), ("nan", lambda: float("nan")), ("array", lambda: np.array([True, False])),
        ("list", lambda: [True]))
#: Junk for a system / a generator / a model object: names and numbers instead of the object.
OBJECT = (("None", lambda: None), ("str", lambda: "siremobile-iso-c3d"), ("int", lambda: 3),
          ("float", lambda: 1.5), ("list", lambda: [1.0]), ("True", lambda: True), ("array", lambda: np.zeros(3)))


def _vector(n: int):
    return (
        ("None", lambda: None), ("True", lambda: True), ("str", lambda: "1,2,3"), ("scalar", lambda: 1.0),
        ("0-d str array", lambda: np.array("1")), ("str array", lambda: np.full(n, "1")),
        ("bool array", lambda: np.ones(n, dtype=bool)), ("complex array", lambda: np.zeros(n) + 1e-3j),
        ("short list", lambda: [0.0] * (n - 1)), ("long list", lambda: [0.0] * (n + 1)),
        ("2-d", lambda: np.zeros((n, 2))), ("nan entry", lambda: np.r_[np.nan, np.zeros(n - 1)]),
        ("inf entry", lambda: np.r_[np.zeros(n - 1), np.inf]), ("huge entry", lambda: np.r_[1e300, np.zeros(n - 1)]),
        ("list of str", lambda: ["0"] * n), ("list of None", lambda: [None] * n),
    )


def wrong_for(kind: str) -> tuple:
    """``(label, make)`` pairs of junk for an argument of ``kind`` (see the module docstring); ``kind`` may end
    in ``?`` (the argument is optional: None is its default, so None is not junk)."""
    optional = kind.endswith("?")
    kind = kind.rstrip("?")
    if kind == "count":
        table = NUMBER + COUNT
    elif kind == "real":
        table = NUMBER
    elif kind.startswith("vector:"):
        table = _vector(int(kind.split(":")[1]))
    elif kind == "grid":  # any number of real values: a wrong length is not junk
        table = tuple(item for item in _vector(2) if item[0] not in ("short list", "long list", "scalar",
                                                                            "list of None"))
    elif kind == "repeats":  # one value per repeat, None or NaN for a failed one
        table = tuple(item for item in wrong_for("grid") if item[0] != "nan entry")
        return table
    elif kind == "seed":  # a numpy seed: an integer >= 0 of any size
        table = tuple(item for item in NUMBER + COUNT if item[0] != "10**30")
    elif kind == "name":
        table = NAME
    elif kind == "joint":  # a joint's name or index: an int in range is not junk, a negative or too large one is
        table = tuple(item for item in NAME if item[0] != "int") + (("-1", lambda: -1), ("99", lambda: 99))
    elif kind == "flag":
        table = FLAG
    elif kind in ("system", "rng", "model"):
        table = OBJECT
    elif kind == "label":  # any string (a name shown to the user): junk is every other type
        table = tuple(item for item in OBJECT if item[0] != "str")
    else:
        raise ValueError(f"unknown argument kind {kind!r}")
    table = ANY + table
    return tuple(item for item in table if not (optional and item[0] == "None"))


def junk_argument(rng: np.random.Generator, case: Case, spec: dict[str, str], extra: dict | None = None,
                  named: dict | None = None) -> Case:
    """``case`` (every argument of ``spec`` passed by keyword) with one argument of ``spec`` (a mapping of
    argument names to kinds) replaced by junk of its kind or by one of ``extra[name]`` (``(label, make)``
    pairs of argument-specific junk: an out-of-range value). The case then expects a typed error whose message
    names the argument (or ``named[name]``, the word its messages use: "preset" for ``name_or_path``)."""
    names = list(spec)
    name = names[int(rng.integers(0, len(names)))]
    table = wrong_for(spec[name]) + tuple((extra or {}).get(name, ()))
    label, make = table[int(rng.integers(0, len(table)))]
    return Case(case.fn, case.args, {**case.kwargs, name: make()}, None, f"{name} ({label})",
                named=(named or {}).get(name, name))


def maybe_junk_argument(rng: np.random.Generator, case: Case, spec: dict[str, str], extra: dict | None = None,
                        fraction: float = 0.5, named: dict | None = None) -> Case:
    """With probability ``fraction``, :func:`junk_argument`; else ``case`` unchanged."""
    return junk_argument(rng, case, spec, extra, named) if rng.random() < fraction else case
