"""Does one error model explain all of them? Seed vs simulation for every number, with a verdict each.

The model fitted on §4.6.2 (:data:`~.fit.BEST_FIT`) runs unchanged on §4.6.3 and Tables 3.1–3.2. Each
experiment is repeated ``repeats`` times (different numpy seeds); for each of the seed's numbers the
simulated value is the mean over the repeats and its spread their standard deviation. The seed's own
sampling error is that of its independent units — procedures, not markers, since the markers of one
procedure share its pose errors: ``std / √procedures`` for a mean (none for a single measured value of
Table 3.2). A number is **reproduced** when ``|seed − simulated| < 2 √(spread² + seed error²)``, **not
reproduced** otherwise, and **undetermined** when it depends only on what the seed does not state (the
marker counts: the phantoms' layouts are assumptions), when no repeat succeeded, or when it is within
2 σ only because the repeats spread over more than half their mean (:data:`WIDE`) — unless at least four
repeats all lie on one side of the seed's number: then it is not reproduced (all four on one side of a
value they are consistent with has probability at most 2/5 by exchangeability; the statement is weak and
the table says so).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .error_model import ErrorModel

#: Reproduced when within this many combined standard errors.
Z_LIMIT = 2.0
#: A simulated value whose repeats spread more than this fraction of their mean cannot confirm a seed
#: number (a wide spread makes any positive number "within 2 σ"): undetermined instead of reproduced.
WIDE = 0.5


@dataclass(frozen=True)
class Row:
    """One number: experiment, quantity, seed value, simulated mean and spread, z, verdict, reason."""

    experiment: str
    quantity: str
    seed: float
    simulated: float
    spread: float
    z: float
    verdict: str
    reason: str


def judge(experiment: str, quantity: str, seed: float, values, seed_error: float = 0.0, reason: str = "") -> Row:
    """A :class:`Row` from the simulated ``values`` (one per repeat) of a seed number (see the module doc)."""
    values = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    if values.size == 0:
        return Row(experiment, quantity, seed, math.nan, math.nan, math.nan, "undetermined", "no repeat succeeded")
    mean, spread = float(values.mean()), float(values.std(ddof=1)) if values.size > 1 else 0.0
    scale = math.sqrt(spread**2 + seed_error**2)
    z = (seed - mean) / scale if scale > 0 else (0.0 if seed == mean else math.copysign(math.inf, seed - mean))
    if abs(z) < Z_LIMIT and spread > WIDE * abs(mean) and not values.min() <= seed <= values.max() and values.size >= 4:
        return Row(experiment, quantity, seed, mean, spread, z, "not reproduced",
                   f"outside all {values.size} repeats ({values.min():.3g} to {values.max():.3g}); |z| = {abs(z):.1f} "
                   "only through their spread")
    if abs(z) < Z_LIMIT and spread > WIDE * abs(mean):
        return Row(experiment, quantity, seed, mean, spread, z, "undetermined",
                   f"|z| = {abs(z):.1f}, but the repeats spread over more than half their mean: more repeats needed")
    verdict = "reproduced" if abs(z) < Z_LIMIT else "not reproduced"
    return Row(experiment, quantity, seed, mean, spread, z, verdict, reason or f"|z| = {abs(z):.1f}")


def rows_4_6_2(system, model: ErrorModel, repeats: int, tasks: int = 10) -> list[Row]:
    from carmkin.seed import SEED_RESULTS

    from .repositioning import run, summary

    runs = [summary(run(system, model, tasks, seed)) for seed in range(repeats)]
    out = []
    for key, (mean, std, _, _) in SEED_RESULTS.items():
        out.append(judge("4.6.2", f"mean {key}", mean, [r[key][0] for r in runs], std / math.sqrt(10)))
        out.append(judge("4.6.2", f"std {key}", std, [r[key][1] for r in runs]))
    return out


def rows_4_6_3(system, model: ErrorModel, repeats: int, procedures: int = 5) -> list[Row]:
    from carmkin.seed import SEED_TABLE_4_6

    from .stitching import run, table

    runs = [table(run(system, model, procedures, seed))["overall"] for seed in range(repeats)]
    seed, n = SEED_TABLE_4_6["overall"], 5
    spread = {i: float(np.std([SEED_TABLE_4_6[f"#{k}"][i] for k in range(1, 6)], ddof=1)) for i in (0, 3, 5)}
    names = {0: "mean image error (px)", 1: "std image error (px)", 3: "mean distance error (mm)",
             4: "std distance error (mm)", 5: "mean angle error (deg)", 6: "std angle error (deg)"}
    out = [judge("4.6.3", names[i], seed[i], [r[i] for r in runs],
                 spread[i] / math.sqrt(n) if i in spread else 0.0) for i in names]
    out.append(Row("4.6.3", "markers", seed[2], float(np.mean([r[2] for r in runs])), math.nan, math.nan,
                   "undetermined", "the phantom's layout and the images' field are assumptions"))
    return out


def rows_3_1(system, model: ErrorModel, repeats: int) -> list[Row]:
    from carmkin.seed import SEED_TABLE_3_1

    from .chapter3 import table_3_1

    runs = [table_3_1(system, model, 2, seed)["overall"] for seed in range(repeats)]
    out = []
    for i, label in ((0, "without VDP"), (1, "with VDP")):
        mean, std, _ = SEED_TABLE_3_1["overall"][i]
        per = [SEED_TABLE_3_1[k][i][0] for k in ("#1", "#2")]
        out.append(judge("3.1", f"mean {label} (px)", mean, [r[i][0] for r in runs], float(np.std(per, ddof=1)) / math.sqrt(2)))
        out.append(judge("3.1", f"std {label} (px)", std, [r[i][1] for r in runs]))
    out.append(judge("3.1", "VDP improvement (px)", SEED_TABLE_3_1["overall"][0][0] - SEED_TABLE_3_1["overall"][1][0],
                     [r[0][0] - r[1][0] for r in runs]))
    return out


def rows_3_2(system, model: ErrorModel, repeats: int) -> list[Row]:
    from carmkin.seed import SEED_TABLE_3_2

    from .chapter3 import table_3_2

    runs = [table_3_2(system, model, seed) for seed in range(repeats)]
    return [judge("3.2", f"{key} by {m}", SEED_TABLE_3_2[key][i], [r[m][key] for r in runs])
            for key in SEED_TABLE_3_2 for i, m in enumerate("ABC")]


EXPERIMENTS = {"4.6.2": rows_4_6_2, "4.6.3": rows_4_6_3, "3.1": rows_3_1, "3.2": rows_3_2}


def verdict(system, model: ErrorModel, repeats: int = 3, experiments=tuple(EXPERIMENTS)) -> list[Row]:
    """Every seed number of ``experiments`` under ``model`` (see the module docstring)."""
    return [row for name in experiments for row in EXPERIMENTS[name](system, model, repeats)]


def format_verdict(rows: list[Row]) -> str:
    lines = [f"{'table':<7}{'quantity':<30}{'seed':>9}{'simulated':>18}  verdict (reason)"]
    for r in rows:
        sim = f"{r.simulated:9.2f} ± {r.spread:5.2f}" if np.isfinite(r.spread) else f"{r.simulated:9.2f}"
        lines.append(f"{r.experiment:<7}{r.quantity:<30}{r.seed:9.2f}{sim:>18}  {r.verdict} ({r.reason})")
    counts = {v: sum(r.verdict == v for r in rows) for v in ("reproduced", "not reproduced", "undetermined")}
    lines.append(", ".join(f"{n} {v}" for v, n in counts.items()))
    return "\n".join(lines)
