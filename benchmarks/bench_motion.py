"""Certified motion between views (issue 37): a query suite of view-to-view moves on every preset with a parametric
patient, python benchmarks/bench_motion.py [--quick] [--queries N] [--offline-s S] [--presets a,b].

Per preset: the 16 standard views planned with ``plan_view`` (patient on the table), then queries between them
(every ordered pair) and random reachable pairs (random views ±60° / ±40°, planned) up to N queries (500 by
default, 12 with --quick). Each query is planned by

* **carmkin** (``MotionPlanner.plan``: the certified straight line, else OMPL RRT-Connect over the certified
  checks, default time budget);
* **OMPL's default validator**: the same RRT-Connect with OMPL's own ``DiscreteMotionValidator`` (states every 1 %
  of the space's extent) and the same state check — its paths are then checked densely;
* **today's joint-by-joint plan** (``World.moves``, the manual order, each joint certified alone).

A query carmkin does not solve is given to a long offline run (OMPL AORRTC, ``--offline-s`` a query, 60 s by
default, 5 s with --quick): the solved rate counts the queries for which some run found a path. Every returned
trajectory is checked at dense samples of its time law (no joint moves more than 0.05° / 0.05 mm between
samples; exact coal distances where within 1 mm of the margin) and at 1 kHz against every speed and
acceleration limit. Printed: solved rate, median and p95 planning time (all queries and solved ones), dense
violations (carmkin and OMPL's default validator), limit violations, the duration against the straight line's
time-optimal duration when that line is free, and the gain against the joint-by-joint duration.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

import carmkin  # noqa: E402
from carmkin.model.motion import Timing, move_duration  # noqa: E402
from carmkin.motion import END_TOLERANCE, MotionPlanner, segment_law  # noqa: E402
from carmkin.motion.search import search  # noqa: E402
from carmkin.patient import ParametricPatient  # noqa: E402
from carmkin.views import View, plan_view  # noqa: E402
from carmkin.views.standard import STANDARD_VIEWS, standard_view  # noqa: E402

DENSE_ANGLE, DENSE_LENGTH = math.radians(0.05), 5e-5


def views_of(system, patient, rng, extra):
    """Configurations of the 16 standard views and ``extra`` random views that plan (reachable)."""
    Q = [p.q for p in (plan_view(system, standard_view(n), patient=patient) for n in STANDARD_VIEWS) if p.success]
    tries = 0
    while extra > 0 and tries < 20 * extra:
        tries += 1
        view = View.from_angles(rng.uniform(-60, 60), rng.uniform(-40, 40), (0.0, 0.0, 0.0))
        plan = plan_view(system, view, patient=patient)
        if plan.success:
            Q.append(plan.q)
            extra -= 1
    return np.array(Q)


def dense_ok(planner, Q, times_law=None) -> bool:
    """Every dense sample of the polyline Q keeps the margin (less the certificate's end tolerance)."""
    system = planner.system
    step = np.where(system.prismatic, DENSE_LENGTH, DENSE_ANGLE)
    threshold = planner.margin - END_TOLERANCE - 2e-6
    for a, b in zip(Q[:-1], Q[1:]):
        n = max(1, int(np.ceil(np.max(np.abs(b - a) / step))))
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        if planner.world.clearance(a + t * (b - a), exact_below=planner.margin + 1e-3).min() < threshold:
            return False
    return True


def limits_ok(system, trajectory) -> bool:
    t = np.arange(0.0, trajectory.duration, 1e-3)
    if not len(t):
        return True
    _, qd, qdd = trajectory.sample(t)
    v = np.array([j.speed for j in system.motion.joints])
    a = np.array([j.acceleration for j in system.motion.joints])
    return bool(np.all(np.abs(qd) <= v * (1 + 1e-9)) and np.all(np.abs(qdd) <= a * (1 + 1e-9)))


def bench_preset(name, n_queries, offline_s, rng):
    system = carmkin.load_preset(name)
    patient = ParametricPatient.on_table(system)
    planner = MotionPlanner(system, patient)
    views = views_of(system, patient, rng, extra=max(0, int(math.sqrt(n_queries)) - 10))
    pairs = [(i, j) for i in range(len(views)) for j in range(len(views)) if i != j]
    rng.shuffle(pairs)
    pairs = pairs[:n_queries]
    rows = []
    for i, j in pairs:
        q_a, q_b = views[i], views[j]
        start = time.perf_counter()
        tr = planner.plan(q_a, q_b)
        seconds = time.perf_counter() - start
        row = {"seconds": seconds, "success": tr.success, "method": tr.method}
        if tr.success:
            row["dense_ok"] = dense_ok(planner, tr.waypoints)
            row["limits_ok"] = limits_ok(system, tr)
            row["duration"] = tr.duration
            if tr.method == "straight":
                row["straight_ratio"] = tr.duration / segment_law(system.motion, q_b - q_a).duration \
                    if np.any(q_b != q_a) else 1.0
            row["by_joint"] = move_duration(system.motion, q_a, q_b, Timing.JOINT_BY_JOINT).seconds
            moves = planner.world.moves(q_a, q_b)
            row["by_joint_clear"] = all(m.clear for m in moves)
        else:
            found = search(planner.certifier, q_a, q_b, system.lower, system.upper, planner.speed, planner.margin,
                           offline_s, "aorrtc")
            row["offline_found"] = found.waypoints is not None
        # OMPL's own discrete validator, same search, same state check
        if tr.method != "straight":
            start = time.perf_counter()
            found = search(planner.certifier, np.clip(q_a, system.lower, system.upper),
                           np.clip(q_b, system.lower, system.upper), system.lower, system.upper, planner.speed,
                           planner.margin, 2.0, "rrt-connect", certified=False)
            row["ompl_seconds"] = time.perf_counter() - start
            if found.waypoints is not None:
                row["ompl_dense_ok"] = dense_ok(planner, found.waypoints)
        rows.append(row)
    return rows


def report(name, rows):
    n = len(rows)
    solved = [r for r in rows if r["success"]]
    has_path = len(solved) + sum(r.get("offline_found", False) for r in rows)
    seconds = np.array([r["seconds"] for r in rows])
    solved_s = np.array([r["seconds"] for r in solved]) if solved else np.array([math.nan])
    ompl = [r for r in rows if "ompl_dense_ok" in r]
    ratios = [r["straight_ratio"] for r in solved if "straight_ratio" in r]
    gains = [r["by_joint"] / r["duration"] for r in solved if r["duration"] > 0]
    print(f"{name}: {n} queries, {len(solved)} solved ({sum(r['method'] == 'straight' for r in solved)} straight), "
          f"{has_path} with a path found by some run -> solved {100.0 * len(solved) / max(has_path, 1):.1f} % "
          f"(bound >= 99.5 %)")
    print(f"  planning time: median {np.median(seconds) * 1e3:.1f} ms, p95 {np.percentile(seconds, 95) * 1e3:.0f} ms "
          f"(all queries; bounds 100 ms / 1000 ms); solved: median {np.median(solved_s) * 1e3:.1f} ms, "
          f"p95 {np.percentile(solved_s, 95) * 1e3:.0f} ms")
    print(f"  dense check (0.05° / 0.05 mm, margin): carmkin {sum(not r['dense_ok'] for r in solved)} of "
          f"{len(solved)} violate; OMPL's default validator {sum(not r['ompl_dense_ok'] for r in ompl)} of "
          f"{len(ompl)} returned paths violate")
    print(f"  limits at 1 kHz: {sum(not r['limits_ok'] for r in solved)} of {len(solved)} trajectories exceed a "
          f"speed or acceleration limit")
    if ratios:
        print(f"  free straight line: duration / its time-optimal duration max {max(ratios):.4f} (bound 1.02)")
    if gains:
        print(f"  gain against today's joint-by-joint duration: median {np.median(gains):.2f}x, "
              f"min {min(gains):.2f}x; joint-by-joint clear alone in "
              f"{sum(r['by_joint_clear'] for r in solved)} of {len(solved)}")


def bench_biplane() -> None:
    """Each of the 16 standard frontal views with the lateral at 90°, from rest, both planes moving together."""
    from carmkin.biplane import BiplaneWorld, load_biplane, plan_biplane

    biplane = load_biplane("angio-biplane")
    patient = ParametricPatient.on_table(biplane.frontal)
    planner = MotionPlanner(biplane, patient)
    world = BiplaneWorld(biplane, patient)
    rest = np.array(biplane.rest)
    reached = 0
    for name in STANDARD_VIEWS:
        pair = plan_biplane(biplane, standard_view(name), patient=patient)
        if not pair.success:
            print(f"  {name:<20} no pair to move to: {pair.reason[:110]}")
            continue
        start = time.perf_counter()
        trajectory = planner.plan(rest, pair.q)
        seconds = time.perf_counter() - start
        if not trajectory.success:
            print(f"  {name:<20} not reached: {trajectory.reason[:110]}")
            continue
        Q = trajectory.waypoints
        planes = min(world.planes(a + t * (b - a)).min() for a, b in zip(Q[:-1], Q[1:])
                     for t in np.linspace(0.0, 1.0, 201))
        reached += 1
        print(f"  {name:<20} {trajectory.method}, {trajectory.duration:5.1f} s, certified clearance "
              f"{trajectory.min_clearance * 1e3:6.1f} mm ({' – '.join(trajectory.pair)}), planes apart "
              f"(201 samples a segment) {planes * 1e3:6.1f} mm, planned in {seconds * 1e3:.0f} ms")
    print(f"angio-biplane: {reached} of {len(STANDARD_VIEWS)} standard pairs reached from rest with both planes "
          f"moving together, planes certified clear of each other along the motion")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="12 queries a preset, 5 s offline runs")
    parser.add_argument("--queries", type=int, default=None, help="queries a preset (default 500, 24 quick)")
    parser.add_argument("--offline-s", type=float, default=None, help="offline AORRTC time a query (s)")
    parser.add_argument("--presets", default=None, help="comma-separated presets (default: every single-plane one)")
    args = parser.parse_args()
    n = args.queries or (12 if args.quick else 500)
    offline = args.offline_s or (5.0 if args.quick else 60.0)
    names = [p for p in (args.presets.split(",") if args.presets else carmkin.list_presets()) if p != "angio-biplane"]
    print(f"bench_motion: {n} queries a preset, offline runs {offline:g} s; the biplane's standard pairs last")
    rng = np.random.default_rng(0)
    for name in names:
        report(name, bench_preset(name, n, offline, rng))
    if not args.presets or "angio-biplane" in args.presets.split(","):
        print("angio-biplane (16 standard frontal views, the lateral at 90°, from rest):")
        bench_biplane()
    return 0


if __name__ == "__main__":
    sys.exit(main())
