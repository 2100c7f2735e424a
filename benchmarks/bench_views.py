"""Clinical views (issue 20): a reachability map with free roll and a parametric patient, plan_view, and the
per-view QP loop they replace.

1. ``carmkin.views.reach_map`` of the table origin over primary −90…90° × secondary −45…45° (181 × 91 at 1°;
   --quick: 37 × 19 at 5°) on ``siremobile-iso-c3d`` with ``ParametricPatient.on_table`` (1.75 m, 75 kg), in
   one process and in the default worker processes (one per usable core; the answers must be identical).
   Baseline in the same run: a per-view ``carmkin.qp_ik.solve`` loop on the same cells (an ``AxisTarget`` at
   the source position the C-arm's geometry gives, the orbital offset from the target, the patient as
   obstacles), timed on a random sample of the cells and scaled to the map's cell count.
2. ``plan_view`` median over random views of the same grid.
3. The QP after the closed form on the motorized preset (the cells of a 10° map the held table leaves
   unreachable).
3b. The robot-held C-arm (``robotic-carm``, issue 30): its reach map (91 × 46 at 2°; --quick: 19 × 10 at 10°),
   every cell by the robot's closed form (issue 37, ``carmkin.views.mount``), against a per-view
   ``qp_ik.solve`` loop on sampled cells (``benchmarks/bench_robot_reach.py`` sets it beside the mobile
   C-arm's map on the same grid).
4. The polish between the samples (issue 31): reach_map with and without it, alternated in the same run.
5. No slowdown from the one collision world (issue 27): ``reach_map`` (one process) and ``plan_view`` timed in
   fresh interpreters on today's code and on the code before the world (:data:`BASELINE_REV`), same grid, same
   patient, same margin (20 mm, the views' default then), in the same run; the reachable cells must agree.
   Today's code runs twice: the same sampled search as before (the polish off: what the world changed), and
   as users get it, with issue 31's polish (its cost is section 4's).

    python benchmarks/bench_views.py            # the full 181 × 91 map
    python benchmarks/bench_views.py --quick    # 37 × 19
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import carmkin
from carmkin import qp_ik
from carmkin.patient import ParametricPatient
from carmkin.views import View, plan_view, reach_map, search
from carmkin.views.maps import default_workers

from _timing import row

#: The last commit before the one collision world (issue 27): the "previous code" of section 5.
BASELINE_REV = "dd205b7"
#: Section 5's measurement, run in a fresh interpreter on either code: reach_map (one process) and plan_view
#: median, at the views' former default margin of 20 mm on both.
TIMING_CODE = """
import json, statistics, time
import numpy as np
import carmkin
from carmkin.patient import ParametricPatient
from carmkin.views import View, plan_view, reach_map
{setup}
step = {step}
system = carmkin.load_preset("siremobile-iso-c3d")
patient = ParametricPatient.on_table(system)
target = np.zeros(3)
primary, secondary = np.arange(-90, 91, step), np.arange(-45, 46, step)
reach_map(system, target, [0], [0], patient, margin=0.02)
best = np.inf
for _ in range(2):
    start = time.perf_counter()
    m = reach_map(system, target, primary, secondary, patient, margin=0.02, workers=1)
    best = min(best, time.perf_counter() - start)
rng = np.random.default_rng(0)
times = []
for _ in range(40):
    view = View.from_angles(primary[rng.integers(len(primary))], secondary[rng.integers(len(secondary))], target, patient)
    start = time.perf_counter()
    plan_view(system, view, patient, nearest=False, margin=0.02)
    times.append(time.perf_counter() - start)
print(json.dumps(dict(map=best, plan=statistics.median(times), reachable=m.reachable.astype(int).tolist())))
"""


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    step = 5 if args.quick else 1
    system = carmkin.load_preset("siremobile-iso-c3d")
    patient = ParametricPatient.on_table(system)
    target = np.zeros(3)
    primary, secondary = np.arange(-90, 91, step), np.arange(-45, 46, step)
    reach_map(system, target, [0], [0], patient)  # builds the collision world once (cached), as a session would
    start = time.perf_counter()
    one = reach_map(system, target, primary, secondary, patient, workers=1)
    t_one = time.perf_counter() - start
    start = time.perf_counter()
    m = reach_map(system, target, primary, secondary, patient)
    t_map = time.perf_counter() - start
    # The same cells, configurations and reasons; the clearances to coal's round-off (its GJK starts from
    # the previous query's guess, and the processes query in another order).
    assert np.array_equal(one.q, m.q, equal_nan=True)
    assert all(np.array_equal(getattr(one, f), getattr(m, f)) for f in ("reachable", "reason"))
    worst = float(np.nanmax(np.abs(one.clearance - m.clearance), initial=0.0))
    assert worst < 1e-12
    cells = m.reachable.size
    workers = default_workers()
    parallel = workers > 1 and cells >= search.PARALLEL_MIN_CELLS
    print(f"map {len(primary)} x {len(secondary)} = {cells} cells: {m.reachable.sum()} reachable "
          f"({100 * m.fraction:.1f} %); the default ran {workers if parallel else 1} process(es) and gave the "
          f"configurations of one (clearances equal to {worst:.1e} m)")
    print(f"answered by their first candidate: {int(np.sum(m.rank == 0))} of {int(m.reachable.sum())} reachable cells; "
          f"the last answer at position {int(m.rank.max())} of its cell's search order")
    rng = np.random.default_rng(0)
    sample = [(rng.integers(len(primary)), rng.integers(len(secondary))) for _ in range(20 if args.quick else 60)]
    obstacles = patient.obstacles()
    solved, start = 0, time.perf_counter()
    for i, j in sample:
        d = m.directions[i, j]
        position = target - system.carm.orbital_offset * d
        result = qp_ik.solve(system, qp_ik.AxisTarget(tuple(position), tuple(d)), obstacles=obstacles,
                             options=qp_ik.QPIKOptions(safety_margin=0.02))
        solved += bool(result.success)
    t_qp = (time.perf_counter() - start) / len(sample) * cells
    print(f"per-view qp_ik.solve loop: {solved} of {len(sample)} sampled cells solved (one descent per view, "
          "distance fixed at the orbital offset)")
    print(row("per-view qp_ik.solve loop (scaled to the map)", t_qp, unit="s"))
    print(row("reach_map, 1 process", t_one, t_qp, unit="s"))
    print(row(f"reach_map, the default ({workers if parallel else 1} process(es))", t_map, t_qp, unit="s"))
    times = []
    for i, j in sample:
        view = View.from_angles(primary[i], secondary[j], target, patient)
        start = time.perf_counter()
        plan_view(system, view, patient, nearest=False)
        times.append(time.perf_counter() - start)
    print(row("plan_view median (no nearest-view search)", statistics.median(times), unit="ms"))
    unreachable_nearest(system, times)
    polish_cost(system, patient, target, primary, secondary)
    qp_after_closed_form(target)
    robot_held_map(target, 10 if args.quick else 2)
    against_previous_code(step)


def unreachable_nearest(system, plan_times) -> None:
    """Issue 41: ``plan_view(nearest=True)`` of a view unreachable everywhere (a target 3 m along the table)
    searches every band of the sphere; its CPU time against the median plan without the search (13.1 s before
    the directions were solved as arrays, 6.2 s after, on this shared machine)."""
    view = View.from_direction((0.0, 0.0, 1.0), np.array([0.0, 0.0, 3.0]))
    start = time.process_time()
    plan = plan_view(system, view, None, nearest=True)
    assert not plan.success and plan.nearest is None
    print(row("plan_view, unreachable everywhere, nearest=True (CPU)", time.process_time() - start,
              statistics.median(plan_times), unit="s"))


def polish_cost(system, patient, target, primary, secondary, repeats: int = 5) -> None:
    """The polish between the samples (issue 31, :mod:`carmkin.views.polish`): reach_map (one process) with it
    and without it (``WINDOW`` < 0: the sampled search alone), alternated in the same run, best of
    ``repeats``; the cells only the polish reaches."""
    from carmkin.views import polish

    window = polish.WINDOW
    times = {True: [], False: []}
    maps = {}
    try:
        for _ in range(repeats):
            for on in (False, True):
                polish.WINDOW = window if on else -1.0
                start = time.perf_counter()
                maps[on] = reach_map(system, target, primary, secondary, patient, workers=1)
                times[on].append(time.perf_counter() - start)
    finally:
        polish.WINDOW = window
    gained = int(np.sum(maps[True].reachable & ~maps[False].reachable))
    print(f"the polish between the samples reaches {gained} more cell(s) of the map than the sampled search alone")
    print(row("reach_map, 1 process, sampled search alone", min(times[False]), unit="s"))
    print(row("reach_map, 1 process, with the polish", min(times[True]), min(times[False]), unit="s"))


def against_previous_code(step: int) -> None:
    """Section 5: today's reach_map and plan_view against the code before the one world, in the same run."""
    from _baseline import checkout, run

    old = checkout(BASELINE_REV)
    if old is None:
        print(f"no git history here: the comparison with {BASELINE_REV} (before the one world) is skipped")
        return
    sampled_only = "from carmkin.views import polish\npolish.WINDOW = -1.0  # the sampled search alone, as before"
    before = run(TIMING_CODE.format(step=step, setup=""), old)
    alone = run(TIMING_CODE.format(step=step, setup=sampled_only))
    now = run(TIMING_CODE.format(step=step, setup=""))
    same = before["reachable"] == alone["reachable"]
    gained = int(np.sum(np.array(now["reachable"]) > np.array(before["reachable"])))
    print(f"against the code before the one world ({BASELINE_REV}), margin 20 mm, fresh interpreters, same run: "
          f"{'the same' if same else 'DIFFERENT'} reachable cells from the same sampled search; the polish "
          f"(issue 31, section 4) reaches {gained} more")
    print(row(f"reach_map {len(np.arange(-90, 91, step))} x {len(np.arange(-45, 46, step))}, 1 process, before",
              before["map"], unit="s"))
    print(row("reach_map, now, the same sampled search", alone["map"], before["map"], unit="s"))
    print(row("reach_map, now, with the polish", now["map"], before["map"], unit="s"))
    print(row("plan_view median, before", before["plan"], unit="ms"))
    print(row("plan_view median, now, the same sampled search", alone["plan"], before["plan"], unit="ms"))
    print(row("plan_view median, now, with the polish", now["plan"], before["plan"], unit="ms"))


def qp_after_closed_form(target) -> None:
    """The QP after the closed form on the motorized preset: of the cells of a 10° map that the held table
    leaves unreachable, how many plan_view reaches by freeing the table joints, and at what cost."""
    system = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    patient = ParametricPatient.on_table(system)
    m = reach_map(system, target, np.arange(-90, 91, 10), np.arange(-45, 46, 10), patient)
    cells = list(zip(*np.nonzero(~m.reachable)))
    freed, start = 0, time.perf_counter()
    for i, j in cells:
        view = View.from_angles(m.primary_deg[i], m.secondary_deg[j], target, patient)
        freed += plan_view(system, view, patient, nearest=False).solver == "qp"
    print(f"motorized table, 10° map: the QP after the closed form reaches {freed} of the {len(cells)} cells the held "
          f"table leaves unreachable ({(time.perf_counter() - start) / max(len(cells), 1):.2f} s a cell)")


def robot_held_map(target, step: int) -> None:
    """The reach map of the robot-held C-arm (every cell by the robot's closed form, :mod:`carmkin.views.mount`)
    against a per-view ``qp_ik.solve`` loop (an AxisTarget at the isocentre distance) on sampled cells, scaled."""
    system = carmkin.load_preset("robotic-carm")
    patient = ParametricPatient.on_table(system)
    primary, secondary = np.arange(-90, 91, step), np.arange(-45, 46, step)
    start = time.perf_counter()
    m = reach_map(system, target, primary, secondary, patient)
    t_map = time.perf_counter() - start
    rng = np.random.default_rng(1)
    sample = [(rng.integers(len(primary)), rng.integers(len(secondary))) for _ in range(12)]
    solved, start = 0, time.perf_counter()
    for i, j in sample:
        d = m.directions[i, j]
        position = target - system.carm.orbital_offset * d
        result = qp_ik.solve(system, qp_ik.AxisTarget(tuple(position), tuple(d)), obstacles=patient.obstacles())
        solved += bool(result.success)
    t_qp = (time.perf_counter() - start) / len(sample) * m.reachable.size
    print(f"robotic-carm map {len(primary)} x {len(secondary)}: {int(m.reachable.sum())} of {m.reachable.size} cells "
          f"reachable; per-view qp_ik.solve loop solved {solved} of {len(sample)} sampled cells")
    print(row("robotic-carm: per-view qp_ik.solve loop (scaled to the map)", t_qp, unit="s"))
    print(row("robotic-carm: reach_map (closed form, default workers)", t_map, t_qp, unit="s"))


if __name__ == "__main__":
    main()
