"""Plan a certified motion of the C-arm (and table, mount) from one configuration to a view or another
configuration, around a patient lying on the table.

The start is --q-mm-deg (one value per joint: mm for prismatic, degrees for revolute joints); the goal is a
standard view (--to-view NAME, planned from the start with the view planner) or a configuration
(--to-q-mm-deg). The motion keeps --margin-mm from table, floor and patient along its whole path (certified:
every pair's distance bounded between samples by the chain's speed bounds), takes the straight joint-space line
when it is clear and otherwise a path found by OMPL's RRT-Connect within --time-limit-s; each straight segment
is timed optimally within the preset's joint speeds and accelerations, from rest to rest. Printed: the
waypoints, the duration (s) against today's joint-by-joint duration, and the certified clearance (mm).
--png draws clearance and joint speeds against time; --html writes a page that plays the motion. Exit 1 when no motion is found.
"""

from __future__ import annotations

import argparse

import numpy as np

from . import _common as common
from . import _scene

HELP = "plan a certified, timed motion to a view or a configuration (mm, degrees, s)"
MM = 1000.0


def register(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION", parser_class=type(parser))
    plan = sub.add_parser("plan", help="plan one motion", description=__doc__,
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    common.add_preset_argument(plan)
    common.add_joints_argument(plan, "start configuration")
    goal = plan.add_mutually_exclusive_group(required=True)
    goal.add_argument("--to-view", metavar="NAME", help="goal: a standard view (carmkin views plan --help lists them)")
    goal.add_argument("--to-q-mm-deg", metavar="V0,V1,...",
                      help="goal: a configuration, one value per joint (mm, degrees; --to-q-mm-deg=-5,... when the "
                           "first is negative)")
    _scene.add_patient_arguments(plan, default="parametric")
    plan.add_argument("--margin-mm", type=common.number(0.0, 1000.0, unit="mm"), default=10.0,
                      help="clearance kept along the whole motion (mm, default 10, carmkin.DEFAULT_MARGIN)")
    plan.add_argument("--time-limit-s", type=common.number(1e-3, 600.0, unit="s"), default=2.0,
                      help="time budget of the search when the straight line is blocked (s, default 2)")
    plan.add_argument("--planner", choices=("rrt-connect", "aorrtc", "bit-star", "rrt-star"), default="rrt-connect",
                      help="OMPL planner of the search (default rrt-connect)")
    common.add_json_argument(plan, "the motion")
    common.add_png_argument(plan, "clearance and joint speeds against time")
    plan.add_argument("--html", metavar="FILE",
                      help="write the motion as a page that plays it in the browser (meshcat, no server)")


def run(args: argparse.Namespace) -> int:
    from carmkin.model.motion import Timing, move_duration
    from carmkin.motion import MotionPlanner

    system = common.system_from_args(args)
    if args.q_mm_deg is None:
        start = np.where(system.prismatic, 0.5 * (system.lower + system.upper), 0.0)
        start = np.clip(start, system.lower, system.upper)
    else:
        start = common.parse_joints(args.q_mm_deg, system, "--q-mm-deg")
    patient = _scene.patient_from_args(system, args)
    if args.to_view is not None:
        from carmkin.views import plan_view
        from carmkin.views.standard import standard_view

        view = standard_view(args.to_view)
        view_plan = plan_view(system, view, patient, start, margin=args.margin_mm / MM, motion_plan=False)
        if not view_plan.success:
            print(f"view {args.to_view} not reachable: {view_plan.reason}")
            return 1
        goal = view_plan.q
    else:
        goal = common.parse_joints(args.to_q_mm_deg, system, "--to-q-mm-deg")
    planner = MotionPlanner(system, patient, args.margin_mm / MM)
    trajectory = planner.plan(start, goal, args.time_limit_s, args.planner)
    by_joint = move_duration(system.motion, start, goal, Timing.JOINT_BY_JOINT).seconds
    print(f"preset {system.name}; patient: {_scene.describe_patient(patient, args.patient_position)}; "
          f"margin {args.margin_mm:g} mm")
    print(f"from {common.format_joints(system, start)}")
    print(f"to   {common.format_joints(system, goal)}")
    data = {"preset": system.name, "margin_mm": args.margin_mm, "success": trajectory.success,
            "start": common.joints_json(system, start), "goal": common.joints_json(system, goal),
            "joint_by_joint_duration_s": by_joint}
    if not trajectory.success:
        print(f"no motion: {trajectory.reason}")
        data["reason"] = trajectory.reason
        common.write_json(args, data)
        return 1
    print(f"motion: {trajectory.method}, {len(trajectory.waypoints) - 1} segment(s), {trajectory.duration:.1f} s "
          f"(joint by joint: {by_joint:.1f} s), certified clearance {trajectory.min_clearance * MM:.1f} mm "
          f"({trajectory.pair[0]} – {trajectory.pair[1]}), planned in {trajectory.planning_s:.2f} s")
    for i, (q, t) in enumerate(zip(trajectory.waypoints, trajectory.times)):
        print(f"  {i}: t={t:7.2f} s  {common.format_joints(system, q)}")
    data.update({"method": trajectory.method, "duration_s": trajectory.duration,
                 "min_clearance_mm": trajectory.min_clearance * MM, "closest_pair": list(trajectory.pair),
                 "waypoints": [common.joints_json(system, q) for q in trajectory.waypoints],
                 "times_s": trajectory.times, "planning_s": trajectory.planning_s})
    common.write_json(args, data)
    if args.png:
        from carmkin.motion.figure import trajectory_figure

        trajectory_figure(planner, trajectory, args.png)
        print(f"wrote {args.png}")
    if args.html:
        from carmkin.viz.motion import animation_viewer

        common.output_path(args.html, "--html", ("html", "htm")).write_text(
            animation_viewer(planner, trajectory, patient).static_html(), encoding="utf-8")
        print(f"wrote {args.html}")
    return 0
