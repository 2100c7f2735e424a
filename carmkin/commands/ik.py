"""Closed-form inverse kinematics: joint values that put the X-ray source at a pose relative to the table.

The pose is the X-ray source frame (origin at the source centre, Z = principal axis) in the table frame 0:
  --pose x,y,z,rx,ry,rz   position in mm, orientation as a rotation vector in degrees (axis × angle,
                          R = exp([r]×)); a first value may be negative: --pose -100,...
  --pose-file FILE        FILE.json: {"position_mm": [x, y, z], "rotation_vector_deg": [rx, ry, rz]}
                          or {"matrix_mm": 4x4 homogeneous matrix with its translation in mm};
                          any other file: the 4x4 matrix as text (translation in mm); a matrix that
                          is nearly rigid (typed with 4 decimals, stored in float32) is projected onto
                          the nearest rigid transform with a one-line note on stderr, one farther than
                          ||R^T R - I|| = 1e-3 is refused
--q-mm-deg (one value per joint, mm for prismatic and degrees for revolute joints) is the current
configuration used to choose between the two solutions (§4.4.2; default: zero configuration). Prints both
solutions in mm/degrees with their status and their §4.4.3 validity (collisions, table in the cone), and
the chosen one (--json [FILE] for machines). The closed form is the paper's 6-joint chain: on a preset with a
motorized table the command refuses and names the alternative (carmkin.qp_ik.solve).

Exit code 0 when the chosen solution is within the joint ranges, 1 when no solution is, 2 on bad input,
an unsolvable singular pose or a system the closed form does not cover.
"""

from __future__ import annotations

import argparse

from ._common import (
    JOINTS_FLAG,
    MM_PER_M,
    add_joints_argument,
    add_json_argument,
    add_preset_argument,
    format_joints,
    joint_units,
    joints_json,
    parse_joints,
    parse_pose,
    read_pose,
    require_six_joints,
    system_from_args,
    to_cli_units,
    write_json,
)

HELP = "closed-form IK of an X-ray source pose (mm, degrees): both solutions and the chosen one"


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    pose = parser.add_mutually_exclusive_group(required=True)
    pose.add_argument("--pose", metavar="X,Y,Z,RX,RY,RZ",
                      help="source position (mm) and rotation vector (deg) in the table frame")
    pose.add_argument("--pose-file", metavar="FILE", help="pose as JSON or a 4x4 text matrix (see above)")
    add_joints_argument(parser, "the current configuration, for the choice between the solutions", "zero",
                        old_names=("--current",))
    add_json_argument(parser, "both branches (joints in mm and degrees; residual in m and rad)")


def validity_summary(system, q) -> dict:
    """§4.4.3 validity of q (m, rad) at the one default margin (:data:`carmkin.world.DEFAULT_MARGIN`) in the
    command line's units: valid, reasons, nearest distance and margin (mm)."""
    from carmkin.robot import validity

    report = validity.check(system, q)
    scale = dict(zip(system.joint_names, to_cli_units(system)))
    units = dict(zip(system.joint_names, joint_units(system)))
    reasons = [f"{j.name} out of range by {j.excess * scale[j.name]:+.4g} {units[j.name]}" for j in report.joints]
    reasons += [f"{c.links[0]} {'intersects' if c.distance < 0 else 'touches'} {c.links[1]} "
                f"({c.distance * MM_PER_M:+.1f} mm)" for c in report.collisions]
    if not report.table_in_cone:
        reasons.append("table not in the X-ray cone")
    return {"valid": report.valid, "reasons": reasons, "min_distance_mm": report.min_distance * MM_PER_M,
            "margin_mm": report.margin * MM_PER_M}


def _branch_dict(system, solution, status) -> dict:
    scale = dict(zip(system.joint_names, to_cli_units(system)))
    units = dict(zip(system.joint_names, joint_units(system)))
    return {
        "joints": joints_json(system, solution),
        "status": status.status,
        "within_limits": status.within_limits,
        "excess": {f"{n}_{units[n]}": float(v * scale[n]) for n, v in status.excess.items()},
        "singular": list(status.singular),
        "numerical": status.numerical,
        "residual_m_rad": float(status.residual),
        "validity": validity_summary(system, solution),
    }


def run(args: argparse.Namespace) -> int:
    from carmkin.analytic_ik import solve

    system = system_from_args(args)
    require_six_joints(system, "carmkin ik", "use carmkin.qp_ik.solve(system, T) in Python (it handles motorized "
                       "tables), or --preset siremobile-iso-c3d")
    if args.pose is not None:
        T = parse_pose(args.pose, "--pose")
    else:
        T = read_pose(args.pose_file, "--pose-file")
    q_current = None if args.q_mm_deg is None else parse_joints(args.q_mm_deg, system, JOINTS_FLAG)
    result = solve(system, T, q_current)
    branches = [_branch_dict(system, s, b) for s, b in zip(result.solutions, result.branches)]
    print(f"preset {system.name}; det J = {result.det_j:.4g}; branches (* = chosen):")
    for k, (solution, b) in enumerate(zip(result.solutions, branches)):
        mark = "*" if k == result.chosen else " "
        excess = ", ".join(f"{n.rpartition('_')[0]} {v:+.4f}{' mm' if n.endswith('_mm') else '°'}"
                           for n, v in b["excess"].items())
        print(f"{mark}{k}  {b['status']}{' (numerical)' if b['numerical'] else ''}"
              f"{'; excess ' + excess if excess else ''}")
        print(f"    joints: {format_joints(system, solution, digits=4)}")
        v = b["validity"]
        print(f"    §4.4.3 at margin {v['margin_mm']:g} mm: {'valid' if v['valid'] else 'INVALID: ' + '; '.join(v['reasons'])}; "
              f"nearest part {v['min_distance_mm']:.1f} mm from table/floor")
    chosen = branches[result.chosen]["validity"]
    print(f"chosen: branch {result.chosen} ({'within' if result.valid else 'NOT within'} the joint ranges; "
          f"{'valid' if chosen['valid'] else 'not valid'} by §4.4.3)")
    write_json(args, {"preset": system.name, "chosen": result.chosen, "valid": bool(result.valid),
                      "det_j": result.det_j, "branches": branches})
    return 0 if result.valid else 1
