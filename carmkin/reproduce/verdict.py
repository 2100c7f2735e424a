"""Does one error model explain all of them? Seed vs simulation for every number, with a kind and a verdict.

The model fitted on §4.6.2 (:data:`~.fit.BEST_FIT`) runs unchanged on §4.6.3 and Tables 3.1–3.2. Each
experiment is repeated ``repeats`` times (different numpy seeds), each repeat the seed's own size (ten
tasks, five panoramas, two procedures, one procedure); for each of the seed's numbers the simulated value
is the mean over the repeats and its spread ``s`` their standard deviation.

**Kinds** (:data:`KINDS`). A row is *predicted* when no parameter of the model was fitted to it — the
only rows that count as evidence; *fitted* when the best fit was chosen on it (§4.6.2's six numbers, and the
two rows that read the same seed rotation, 0.37 ± 0.16°, as the angle of the relative rotation: shown,
in-sample, not evidence); *not a test* when the simulated procedure or quantity is not the seed's (a layout
the seed does not state, a procedure that differs from the one the seed describes).

**Criteria** (:data:`ALPHA` is the false-rejection rate of each):

* Where the seed states a tolerance (Table 3.2: "less than 1 % for all cases") the row tests the
  *simulated error* against it: a repeat fails when its error exceeds 1 % of the actual value, and the row is
  not reproduced when so many fail that "at most :data:`TOLERANCE_SHARE` of runs exceed the tolerance" is
  rejected by a one-sided binomial test at ``ALPHA`` (with four repeats: two or more fail).
* Elsewhere the seed's number is one draw of the experiment the repeats simulate, so under the model
  ``(seed − mean) / (s √(1 + 1/n))`` follows Student's t with ``n − 1`` degrees of freedom (normal
  repeats): not reproduced when ``|seed − mean| > t_{n−1, 1−α/2} s √(1 + 1/n)`` — the false-rejection
  rate is ``ALPHA`` exactly for normal repeats. This replaces the former "all four repeats on one side"
  rule, whose false-rejection rate was up to 40 %. The seed's own sampling error is inside ``s``: each
  repeat has the seed's size.
  **Ratio-scale quantities** (a standard deviation, the mean of an error's magnitude: positive, compared
  by factors) take the same test on the logarithms of the seed and the repeats: not reproduced when
  ``|ln seed − mean ln| > t_{n−1, 1−α/2} s_ln √(1 + 1/n)``, i.e. when the seed lies outside a stated factor
  ``exp(t s_ln √(1 + 1/n))`` of the repeats' geometric mean (16.3 ± 6.0 px against 2.6 px is then 6.3× off,
  beyond its factor 2.4, instead of "within 2.51 s").
* **Undetermined**: no repeat succeeded, or the t-test has no power there — its acceptance interval holds
  both 0 and twice the seed's value (on the ratio scale: both half and twice the seed's value; more repeats
  needed). This never turns a rejection into acceptance.

**False acceptance** (each criterion prints it): the probability that the row is called reproduced when the
model is wrong by a stated amount, at the measured spread: on the ratio scale a model off by a factor
:data:`RATIO_ALTERNATIVE` (2), on the linear scale one whose mean is off by the seed's own value (noncentral
t, ``scipy.stats.nct``); for the tolerance test a model with :data:`TOLERANCE_ALTERNATIVE` (30 %) of its
runs above 1 % (binomial).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import SimulationError

from carmkin.validation import real_array, real_scalar

from .error_model import ErrorModel, count, study_inputs

#: The false-rejection rate of every row's test (a value the model does explain is called not reproduced
#: with at most this probability).
ALPHA = 0.05
#: Table 3.2's tolerance test: the share of runs allowed above the seed's 1 % under the null hypothesis
#: "the model meets the seed's claim" (a run above 1 % once in twenty is still "less than 1 % for all
#: cases" to the precision four repeats allow).
TOLERANCE_SHARE = 0.05
#: The seed's stated tolerance of Table 3.2's measurements ("less than 1 % for all cases"), relative.
TABLE_3_2_TOLERANCE = 0.01
#: The ratio-scale criterion's stated alternative: a model off by this factor (either way).
RATIO_ALTERNATIVE = 2.0
#: The tolerance test's stated alternative: this share of the model's runs above the seed's 1 %.
TOLERANCE_ALTERNATIVE = 0.3
#: The two scales of :func:`judge`: "linear" (differences), "ratio" (factors; positive quantities).
SCALES = ("linear", "ratio")
#: The three kinds of row (module docstring).
KINDS = ("predicted", "fitted", "not-a-test")
#: The three verdicts.
VERDICTS = ("reproduced", "not reproduced", "undetermined")


@dataclass(frozen=True)
class Row:
    """One number: experiment, quantity, seed value, simulated mean and spread, the test's statistic and
    its critical value, verdict, kind, the criterion as printed, and why the kind."""

    experiment: str
    quantity: str
    seed: float
    simulated: float
    spread: float
    statistic: float
    critical: float
    verdict: str
    kind: str
    criterion: str
    why: str = ""


def _finite(values) -> np.ndarray:
    """The values of the repeats that succeeded: ``values`` one real number per repeat, None or NaN for a failed
    one (left out); anything else (a string, a dict, a 2-d array, ±inf) is :class:`SimulationError`."""
    if not isinstance(values, (list, tuple, np.ndarray)) or np.ndim(values) == 0:
        raise SimulationError(f"values must be a list of numbers, one per repeat (None: failed), got "
                              f"{type(values).__name__}")
    array = real_array([math.nan if v is None else v for v in values], "values", (None,), error=SimulationError,
                       finite=False)
    if np.any(np.isinf(array)):
        raise SimulationError(f"values must be finite numbers or None (a failed repeat), got {array.tolist()!r:.80}")
    return array[np.isfinite(array)]


def _row_inputs(seed, kind: str) -> float:
    """``seed`` (the seed's number) as a finite real, and ``kind`` one of :data:`KINDS`; else SimulationError."""
    if not isinstance(kind, str) or kind not in KINDS:
        raise SimulationError(f"kind must be one of {', '.join(KINDS)}, got {kind!r:.60}")
    return real_scalar(seed, "seed", error=SimulationError)


#: What the forked workers of :func:`_repeats` run: set before the fork, read by :func:`_one_repeat`.
_FORKED = None


def _one_repeat(seed: int, one=None):
    try:
        return (one or _FORKED)(seed)
    except SimulationError:
        return None


def _repeats(one, repeats: int) -> list:
    """``one(seed)`` for seeds 0 … repeats − 1; a repeat whose procedure failed (:class:`SimulationError`:
    the camera lost the pattern, no first configuration allowed the panorama) is ``None``: its values are
    left out, and each row's criterion states how many repeats it has. The repeats are independent (each its own
    seed), so they run over one forked process per CPU where the platform forks (the same values as one after
    the other: ``tests/reproduce/test_experiments.py``)."""
    import multiprocessing
    import os

    global _FORKED
    seeds = range(count(repeats, "repeats"))
    workers = min(len(seeds), os.cpu_count() or 1)
    if workers < 2 or "fork" not in multiprocessing.get_all_start_methods() or multiprocessing.current_process().daemon:
        return [_one_repeat(seed, one) for seed in seeds]
    _FORKED = one  # a closure over the system and the model: inherited by the fork, never pickled
    try:
        with multiprocessing.get_context("fork").Pool(workers) as pool:
            return pool.map(_one_repeat, seeds, chunksize=1)
    finally:
        _FORKED = None


def _pick(runs, get) -> list:
    return [None if r is None else get(r) for r in runs]


def t_critical(n: int, alpha: float = ALPHA) -> float:
    """``t_{n−1, 1−α/2} √(1 + 1/n)``: the half-width, in repeat standard deviations, of the prediction
    interval a new draw falls in with probability 1 − α (n ≥ 2 normal repeats)."""
    from scipy.stats import t

    return float(t.ppf(1.0 - alpha / 2.0, n - 1) * math.sqrt(1.0 + 1.0 / n))


def false_acceptance(offset: float, spread: float, n: int, alpha: float = ALPHA) -> float:
    """The probability that the prediction t-test (n repeats of spread ``spread``) accepts a seed whose
    expected value is ``offset`` away from the repeats' (noncentral t with n − 1 degrees of freedom)."""
    from scipy.stats import nct, t

    if spread <= 0:
        return 0.0
    c = float(t.ppf(1.0 - alpha / 2.0, n - 1))
    delta = abs(offset) / (spread * math.sqrt(1.0 + 1.0 / n))
    return float(nct.cdf(c, n - 1, delta) - nct.cdf(-c, n - 1, delta))


def judge(experiment: str, quantity: str, seed: float, values, kind: str = "predicted", why: str = "",
          scale: str = "linear") -> Row:
    """A :class:`Row` by the prediction t-test of the module docstring, on the ``scale`` of :data:`SCALES`
    ("ratio": the test on logarithms, for positive quantities compared by factors)."""
    seed, values = _row_inputs(seed, kind), _finite(values)
    if not isinstance(scale, str) or scale not in SCALES:
        raise SimulationError(f"scale must be one of {', '.join(SCALES)}, got {scale!r:.60}")
    if values.size == 0:
        return Row(experiment, quantity, seed, math.nan, math.nan, math.nan, math.nan, "undetermined", kind,
                   "no repeat succeeded", why)
    mean = float(values.mean())
    if values.size < 2:
        return Row(experiment, quantity, seed, mean, math.nan, math.nan, math.nan, "undetermined", kind,
                   "one repeat: no spread to test against", why)
    spread, critical = float(values.std(ddof=1)), t_critical(values.size)
    if scale == "ratio":
        if seed <= 0 or np.any(values <= 0):
            return Row(experiment, quantity, seed, mean, spread, math.nan, math.nan, "undetermined", kind,
                       "a ratio-scale number ≤ 0: no factor to test", why)
        logs = np.log(values)
        log_spread = float(logs.std(ddof=1))
        half = critical * log_spread
        statistic = abs(math.log(seed) - float(logs.mean()))
        far = false_acceptance(math.log(RATIO_ALTERNATIVE), log_spread, values.size)
        criterion = (f"|ln(seed / sim)| {statistic:.3g} vs {critical:.2f} s_ln = {half:.3g} (t on logs, n = "
                     f"{values.size}, α {ALPHA:g}: within × {math.exp(half):.3g}); accepts a model off × "
                     f"{RATIO_ALTERNATIVE:g} with p {far:.2f}")
        no_power = half >= math.log(2.0) + abs(float(logs.mean()) - math.log(seed)) and statistic <= half
        power_text = ": no power, the interval holds seed / 2 and 2 × seed"
    else:
        half = critical * spread
        statistic = abs(seed - mean)
        far = false_acceptance(seed, spread, values.size)
        criterion = (f"|seed − sim| {statistic:.3g} vs {critical:.2f} s = {half:.3g} (t, n = {values.size}, α "
                     f"{ALPHA:g}); accepts a model off by the seed's value with p {far:.2f}")
        no_power = mean - half <= 0.0 <= mean + half and mean - half <= 2.0 * seed <= mean + half and seed > 0
        power_text = ": no power, the interval holds 0 and 2 × seed"
    if statistic > half:
        verdict = "not reproduced"
    elif no_power:
        verdict, criterion = "undetermined", criterion + power_text
    else:
        verdict = "reproduced"
    return Row(experiment, quantity, seed, mean, spread, statistic, half, verdict, kind, criterion, why)


def tolerance_failures_allowed(n: int, alpha: float = ALPHA, share: float = TOLERANCE_SHARE) -> int:
    """The largest number of ``n`` repeats above the tolerance that the one-sided binomial test at ``alpha``
    still accepts under "at most ``share`` of runs exceed it"."""
    from scipy.stats import binom

    return next(k for k in range(n + 1) if binom.sf(k, n, share) <= alpha)


def judge_tolerance(experiment: str, quantity: str, seed: float, actual: float, values, kind: str = "predicted",
                    why: str = "") -> Row:
    """A :class:`Row` testing the simulated relative errors ``|value − actual| / actual`` against the seed's
    stated tolerance :data:`TABLE_3_2_TOLERANCE` (module docstring)."""
    seed, values = _row_inputs(seed, kind), _finite(values)
    actual = real_scalar(actual, "actual", error=SimulationError)
    if actual == 0:
        raise SimulationError("actual must be non-zero (errors are relative to it), got 0")
    if values.size == 0:
        return Row(experiment, quantity, seed, math.nan, math.nan, math.nan, math.nan, "undetermined", kind,
                   "no repeat succeeded", why)
    errors = np.abs(values - actual) / abs(actual)
    failures, allowed = int(np.count_nonzero(errors > TABLE_3_2_TOLERANCE)), tolerance_failures_allowed(values.size)
    verdict = "not reproduced" if failures > allowed else "reproduced"
    from scipy.stats import binom

    far = float(binom.cdf(allowed, values.size, TOLERANCE_ALTERNATIVE))
    criterion = (f"error < {100 * TABLE_3_2_TOLERANCE:g} % (seed's claim): {failures} of {values.size} repeats above "
                 f"(max {100 * errors.max():.2f} %), ≤ {allowed} allowed (binomial, α {ALPHA:g}); accepts a model "
                 f"with {TOLERANCE_ALTERNATIVE:.0%} of runs above with p {far:.2f}")
    spread = float(values.std(ddof=1)) if values.size > 1 else math.nan
    return Row(experiment, quantity, seed, float(values.mean()), spread, float(failures), float(allowed), verdict,
               kind, criterion, why)


#: Why §4.6.2's six rows are fitted: the best fit minimises their χ².
FITTED_4_6_2 = "the best fit (corner noise, operator scale) was chosen on this number"


#: Why §4.6.2's two rotation-angle rows are fitted too: they re-test the seed numbers the fit was chosen on.
ROTATION_ANGLE = ("the seed's rotation (0.37 ± 0.16°) read as the angle of the relative rotation: the same two "
                  "numbers the fit was chosen on (axes reading), so in-sample")


#: Why the ``"box"`` end's rows are no test: the end state is stated, not the seed's guided moves.
BOX_END = "the operator's end is stated (within 0.5 mm / 0.1° per joint), not simulated: a hypothesis, not the seed's procedure"


def rows_4_6_2(system, model: ErrorModel, repeats: int, tasks: int = 10, end: str = "guided") -> list[Row]:
    """§4.6.2's six numbers (fitted), and the rotation's other reading (predicted); with ``end="box"``
    all not a test (:data:`BOX_END`)."""
    from carmkin.seed import SEED_RESULTS as SEED

    from .repositioning import run, summary

    runs = _repeats(lambda seed: summary(run(system, model, tasks, seed, end=end)), repeats)
    name, out = ("4.6.2", []) if end == "guided" else ("4.6.2 box", [])
    fitted = ("fitted", FITTED_4_6_2) if end == "guided" else ("not-a-test", BOX_END)
    for key, (mean, std, _, _) in SEED.items():
        out.append(judge(name, f"mean {key}", mean, _pick(runs, lambda r: r[key][0]), *fitted, scale="ratio"))
        out.append(judge(name, f"std {key}", std, _pick(runs, lambda r: r[key][1]), *fitted, scale="ratio"))
    mean, std = SEED["rotation (deg)"][:2]
    kind, why = ("fitted", ROTATION_ANGLE) if end == "guided" else ("not-a-test", BOX_END)
    out.append(judge(name, "mean rotation angle (deg)", mean, _pick(runs, lambda r: r["rotation angle (deg)"][0]),
                     kind, why, scale="ratio"))
    out.append(judge(name, "std rotation angle (deg)", std, _pick(runs, lambda r: r["rotation angle (deg)"][1]),
                     kind, why, scale="ratio"))
    return out


def rows_4_6_3(system, model: ErrorModel, repeats: int, procedures: int = 5) -> list[Row]:
    from carmkin.seed import SEED_TABLE_4_6

    from .stitching import run, table

    runs = _repeats(lambda seed: table(run(system, model, procedures, seed))["overall"], repeats)
    seed = SEED_TABLE_4_6["overall"]
    names = {0: "mean image error (px)", 1: "std image error (px)", 3: "mean distance error (mm)",
             4: "std distance error (mm)", 5: "mean angle error (deg)", 6: "std angle error (deg)"}
    out = [judge("4.6.3", names[i], seed[i], _pick(runs, lambda r, i=i: r[i]), scale="ratio") for i in names]
    markers = float(np.mean(_finite(_pick(runs, lambda r: r[2])))) if any(r is not None for r in runs) else math.nan
    out.append(Row("4.6.3", "markers", seed[2], markers, math.nan, math.nan, math.nan, "undetermined", "not-a-test",
                   "none: the phantom's layout and the images' field are assumptions",
                   "the count follows the assumed layout"))
    return out


#: Why chapter 3's rows under chapter 4's procedure are no test of the seed's.
CHAPTER_4_PROCEDURE = ("simulated with chapter 4's guidance (planner, 2 mm / 0.5° stop, planned homography), not "
                       "§3.3.4.2's (table moved until the source translation is below 1 mm, homography from the "
                       "measured pose)")


def _chapter3(protocol: str) -> tuple[str, str, str]:
    """(experiment suffix, kind, why) of chapter 3's rows under ``protocol``."""
    return ("", "predicted", "") if protocol == "chapter3" else (" ch4", "not-a-test", CHAPTER_4_PROCEDURE)


def rows_3_1(system, model: ErrorModel, repeats: int, protocol: str = "chapter3") -> list[Row]:
    from carmkin.seed import SEED_TABLE_3_1

    from .chapter3 import table_3_1

    suffix, kind, why = _chapter3(protocol)
    runs = _repeats(lambda seed: table_3_1(system, model, 2, seed, protocol=protocol)["overall"], repeats)
    out = []
    for i, label in ((0, "without VDP"), (1, "with VDP")):
        mean, std, _ = SEED_TABLE_3_1["overall"][i]
        out.append(judge("3.1" + suffix, f"mean {label} (px)", mean, _pick(runs, lambda r, i=i: r[i][0]), kind, why,
                         scale="ratio"))
        out.append(judge("3.1" + suffix, f"std {label} (px)", std, _pick(runs, lambda r, i=i: r[i][1]), kind, why,
                         scale="ratio"))
    out.append(judge("3.1" + suffix, "VDP improvement (px)",
                     SEED_TABLE_3_1["overall"][0][0] - SEED_TABLE_3_1["overall"][1][0],
                     _pick(runs, lambda r: r[0][0] - r[1][0]), kind, why))
    return out


#: The actual values of Table 3.2's rows (mm or degrees).
ACTUAL_3_2 = {"240 mm": 240.0, "120 mm": 120.0, "90 deg": 90.0, "180 deg": 180.0}


def rows_3_2(system, model: ErrorModel, repeats: int, protocol: str = "chapter3") -> list[Row]:
    """Table 3.2's rows; under ``"chapter4"`` only A and B (C's one-plane stitching has no protocol choice)."""
    from carmkin.seed import SEED_TABLE_3_2

    from .chapter3 import table_3_2

    suffix, kind, why = _chapter3(protocol)
    runs = _repeats(lambda seed: table_3_2(system, model, seed, protocol=protocol), repeats)
    return [judge_tolerance("3.2" + suffix, f"{key} by {m}", SEED_TABLE_3_2[key][i], ACTUAL_3_2[key],
                            _pick(runs, lambda r, m=m, key=key: r[m][key]), kind if m != "C" else "predicted", why if m != "C" else "")
            for key in SEED_TABLE_3_2 for i, m in enumerate("ABC") if protocol == "chapter3" or m != "C"]


EXPERIMENTS = {"4.6.2": rows_4_6_2, "4.6.3": rows_4_6_3, "3.1": rows_3_1, "3.2": rows_3_2,
               "4.6.2 box": functools.partial(rows_4_6_2, end="box"),
               "3.1 ch4": functools.partial(rows_3_1, protocol="chapter4"),
               "3.2 ch4": functools.partial(rows_3_2, protocol="chapter4")}


def verdict(system, model: ErrorModel, repeats: int = 8, experiments=tuple(EXPERIMENTS)) -> list[Row]:
    """Every seed number of ``experiments`` (names of :data:`EXPERIMENTS`, or one name) under ``model`` (see the
    module docstring); ``repeats`` >= 2 (the prediction test needs a spread)."""
    study_inputs(system, model)
    if count(repeats, "repeats") < 2:
        raise SimulationError(f"repeats must be >= 2 (the prediction t-test needs a spread), got {repeats}")
    experiments = (experiments,) if isinstance(experiments, str) else experiments
    if not isinstance(experiments, (list, tuple)) or not experiments or not all(
            isinstance(name, str) and name in EXPERIMENTS for name in experiments):
        raise SimulationError(f"experiments must be names of {', '.join(EXPERIMENTS)}, got {experiments!r:.80}")
    return [row for name in experiments for row in EXPERIMENTS[name](system, model, repeats)]


def across(rows_by_point) -> list[Row]:
    """The rows of the first point (the best fit), each verdict kept only when every other point of the fit's
    95 % region gives the same verdict for that row; otherwise "undetermined", the criterion naming the
    verdicts per point. ``rows_by_point``: a list of row lists, one per point, the same rows in the same order."""
    if not isinstance(rows_by_point, (list, tuple)) or not rows_by_point or not all(
            isinstance(rows, (list, tuple)) and all(isinstance(r, Row) for r in rows) for rows in rows_by_point):
        raise SimulationError("rows_by_point must be a non-empty list of lists of Row, one per point of the region")
    best = rows_by_point[0]
    if any([(r.experiment, r.quantity) for r in rows] != [(r.experiment, r.quantity) for r in best]
           for rows in rows_by_point):
        raise SimulationError("rows_by_point: every point must give the same rows in the same order")
    out = []
    for i, row in enumerate(best):
        verdicts = [rows[i].verdict for rows in rows_by_point]
        if len(set(verdicts)) == 1:
            out.append(row)
        else:
            out.append(dataclasses.replace(row, verdict="undetermined", criterion=(
                f"{row.criterion}; across the fit's 95 % region: {', '.join(verdicts)}")))
    return out


def verdict_over_region(system, models, repeats: int = 8, experiments=tuple(EXPERIMENTS)) -> list[Row]:
    """:func:`verdict` under each of ``models`` (the best fit first, then the other points of its 95 % region:
    :func:`region_models`), combined by :func:`across`: a verdict holds only where it holds at every point."""
    if not isinstance(models, (list, tuple)) or not models or not all(isinstance(m, ErrorModel) for m in models):
        raise SimulationError("models must be a non-empty list of ErrorModel, the best fit first")
    return across([verdict(system, model, repeats, experiments) for model in models])


def region_models(base: ErrorModel, region=None) -> list[ErrorModel]:
    """``base`` at each (corner noise px, operator scale) of ``region`` (default :data:`.fit.FIT_REGION`)."""
    from .fit import FIT_REGION

    if not isinstance(base, ErrorModel):
        raise SimulationError(f"base must be an ErrorModel, got {type(base).__name__}")
    points = real_array(FIT_REGION if region is None else region, "region", (None, 2), error=SimulationError)
    return [base.replace(corner_noise_px=float(c)).with_operator_scale(float(s)) for c, s in points]


def counts(rows: list[Row]) -> dict:
    """kind -> verdict -> number of rows."""
    return {kind: {v: sum(r.kind == kind and r.verdict == v for r in rows) for v in VERDICTS} for kind in KINDS}


def format_counts(rows: list[Row], judged: str = "") -> str:
    """The tally line; ``judged`` (e.g. "judged across the fit's 95 % region ...") is appended after "; "."""
    c = counts(rows)
    total = {k: sum(v.values()) for k, v in c.items()}
    return (f"predicted {total['predicted']} ({c['predicted']['reproduced']} reproduced, "
            f"{c['predicted']['not reproduced']} not reproduced, {c['predicted']['undetermined']} undetermined); "
            f"fitted {total['fitted']} (in-sample, not evidence); not a test {total['not-a-test']}"
            + (f"; {judged}" if judged else ""))


def format_verdict(rows: list[Row], judged: str = "") -> str:
    lines = [f"{'table':<10}{'quantity':<28}{'seed':>8}{'simulated':>17}  {'kind':<11}{'verdict':<16}criterion"]
    for r in rows:
        sim = f"{r.simulated:8.2f} ± {r.spread:5.2f}" if np.isfinite(r.spread) else f"{r.simulated:8.2f}"
        lines.append(f"{r.experiment:<10}{r.quantity:<28}{r.seed:8.2f}{sim:>17}  {r.kind:<11}{r.verdict:<16}{r.criterion}")
    lines.append(format_counts(rows, judged))
    return "\n".join(lines)
