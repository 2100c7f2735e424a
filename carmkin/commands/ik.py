"""Closed-form inverse kinematics: joint values that put the X-ray source at a pose relative to the table.

The pose is the X-ray source frame (origin at the source centre, Z = principal axis) in the table frame 0:
  --pose x,y,z,rx,ry,rz   position in mm, orientation as a rotation vector in degrees (axis × angle,
                          R = exp([r]×)); write --pose=-100,... when the first value is negative
  --pose-file FILE.json   {"position_mm": [x, y, z], "rotation_vector_deg": [rx, ry, rz]}
                          or {"matrix_mm": 4x4 homogeneous matrix with its translation in mm}
--current d0,d1,θ2,d3,θ4,θ5 (mm for d*, degrees for θ*) is the current configuration used to choose
between the two solutions (§4.4.2; default: zero configuration). Prints both solutions in mm/degrees with
their status and the chosen one (--json for machines). Exit code 0 when the chosen solution is within the
joint ranges, 1 when no solution is, 2 on bad input or an unsolvable singular pose.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from carmkin.analytic_ik import solve
from carmkin.errors import InvalidConfigurationError, InvalidPoseError
from carmkin.model.params import JOINT_NAMES, PRISMATIC

from ._common import add_preset_argument, system_from_args

HELP = "closed-form IK of an X-ray source pose (mm, degrees): both solutions and the chosen one"

#: Factor from SI (m, rad) to the CLI units (mm, degrees), per joint.
TO_CLI = np.array([1000.0 if p else 180.0 / math.pi for p in PRISMATIC])
UNITS = tuple("mm" if p else "deg" for p in PRISMATIC)


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    pose = parser.add_mutually_exclusive_group(required=True)
    pose.add_argument("--pose", metavar="X,Y,Z,RX,RY,RZ",
                      help="source position (mm) and rotation vector (deg) in the table frame")
    pose.add_argument("--pose-file", metavar="FILE.json", help="pose as JSON (see above)")
    parser.add_argument("--current", metavar="D0,D1,T2,D3,T4,T5",
                        help="current joints (mm, deg) for the choice between the solutions (default: zero)")
    parser.add_argument("--json", action="store_true",
                        help="print JSON (joints in mm and degrees; residual in m and rad)")


def _numbers(text: str, count: int, name: str, error) -> np.ndarray:
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError as exc:
        raise error(f"{name}: expected {count} comma-separated numbers, got {text!r}") from exc
    if values.shape != (count,) or not np.all(np.isfinite(values)):
        raise error(f"{name}: expected {count} finite comma-separated numbers, got {text!r}")
    return values


def pose_from_cli(position_mm, rotation_vector_deg) -> np.ndarray:
    """4x4 pose (m) from a position in mm and a rotation vector in degrees."""
    import pinocchio as pin

    T = np.eye(4)
    T[:3, :3] = pin.exp3(np.radians(np.asarray(rotation_vector_deg, dtype=float)))
    T[:3, 3] = np.asarray(position_mm, dtype=float) / 1000.0
    return T


def read_pose_file(path: str) -> np.ndarray:
    """The pose (m) of a JSON file, see the module docstring."""
    try:
        with open(path) as stream:
            content = json.load(stream)
    except (OSError, json.JSONDecodeError) as exc:
        raise InvalidPoseError(f"--pose-file {path}: {exc}") from exc
    if not isinstance(content, dict):
        raise InvalidPoseError(f"--pose-file {path}: expected a JSON object")
    if "matrix_mm" in content:
        try:
            T = np.array(content["matrix_mm"], dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidPoseError(f"--pose-file {path}: matrix_mm must be a 4x4 array of numbers") from exc
        if T.shape != (4, 4):
            raise InvalidPoseError(f"--pose-file {path}: matrix_mm must be 4x4, got shape {T.shape}")
        T[:3, 3] /= 1000.0
        return T
    try:
        position = np.array(content["position_mm"], dtype=float)
        rotation = np.array(content["rotation_vector_deg"], dtype=float)
    except KeyError as exc:
        raise InvalidPoseError(f"--pose-file {path}: missing key {exc}; expected position_mm and "
                               "rotation_vector_deg, or matrix_mm") from exc
    except (TypeError, ValueError) as exc:
        raise InvalidPoseError(f"--pose-file {path}: position_mm/rotation_vector_deg must be numbers") from exc
    if position.shape != (3,) or rotation.shape != (3,) or not np.all(np.isfinite(np.r_[position, rotation])):
        raise InvalidPoseError(f"--pose-file {path}: position_mm and rotation_vector_deg need 3 finite values")
    return pose_from_cli(position, rotation)


def _branch_dict(solution, status) -> dict:
    names = JOINT_NAMES
    return {
        "joints": {f"{n}_{u}": float(v) for n, u, v in zip(names, UNITS, solution * TO_CLI)},
        "status": status.status,
        "within_limits": status.within_limits,
        "excess": {f"{n}_{UNITS[names.index(n)]}": float(v * TO_CLI[names.index(n)]) for n, v in status.excess.items()},
        "singular": list(status.singular),
        "numerical": status.numerical,
        "residual_m_rad": float(status.residual),
    }


def run(args: argparse.Namespace) -> int:
    system = system_from_args(args)
    if args.pose is not None:
        values = _numbers(args.pose, 6, "--pose", InvalidPoseError)
        T = pose_from_cli(values[:3], values[3:])
    else:
        T = read_pose_file(args.pose_file)
    q_current = None
    if args.current is not None:
        q_current = _numbers(args.current, 6, "--current", InvalidConfigurationError) / TO_CLI
    result = solve(system, T, q_current)
    branches = [_branch_dict(s, b) for s, b in zip(result.solutions, result.branches)]
    if args.json:
        print(json.dumps({"preset": system.name, "chosen": result.chosen, "valid": bool(result.valid),
                          "det_j": result.det_j, "branches": branches}, indent=2))
    else:
        print(f"preset {system.name}; det J = {result.det_j:.4g}")
        header = "".join(f"{n[:12] + ' (' + u + ')':>19}" for n, u in zip(JOINT_NAMES, UNITS))
        print(f"{'branch':<8}{header}  status")
        for k, b in enumerate(branches):
            mark = "*" if k == result.chosen else " "
            values = "".join(f"{v:>19.4f}" for v in b["joints"].values())
            extra = "" if not b["excess"] else "  excess " + ", ".join(f"{n} {v:+.4f}" for n, v in b["excess"].items())
            print(f"{mark}{k:<7}{values}  {b['status']}{' (numerical)' if b['numerical'] else ''}{extra}")
        print(f"chosen: branch {result.chosen} ({'within' if result.valid else 'NOT within'} the joint ranges)")
    return 0 if result.valid else 1
