"""RTK's geometry file written without RTK: the XML of ``rtk::ThreeDCircularProjectionGeometryXMLFileWriter``.

RTK describes each projection by nine numbers (gantry, out-of-plane and in-plane angles in degrees; source to
isocentre and source to detector distances; source and detector offsets) and its 3x4 matrix. Given the source
S, the detector's centre R and its unit row and column directions r, c of a frame (world units, mm here),
:func:`projection_parameters` decomposes them as RTK's ``AddProjection(S, R, r, c)`` does (Euler angles in ITK's
ZXY order of the matrix with rows r, c, n = r x c, then negated; SID = n.S, SDD = n.(S - R); offsets S.r, S.c,
R.r, R.c), :func:`projection_matrix` composes RTK's matrix from them, and :func:`write` writes the file as RTK's
writer does (a value equal over every projection is written once, before the projections; a zero angle or offset
is left out; 15 significant digits). ``tests/sweeps/test_export.py`` reads the file back with RTK's own reader
when itk-rtk is installed.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from carmkin.errors import SweepError

#: Largest difference between the detector's rotation and the one rebuilt from the extracted Euler angles.
ANGLE_CHECK_TOLERANCE = 1e-6
#: How close |R[2, 1]| may come to 1 before the angles are taken as gimbal-locked (z = 0).
GIMBAL_TOLERANCE = 1e-6
#: Tolerance on r . c of a detector whose row and column directions RTK accepts as orthogonal (RTK's own 1e-6).
ORTHOGONALITY_TOLERANCE = 1e-6
#: RTK's file format version written in the root element.
VERSION = 3
#: The per-projection fields, in the order RTK writes them (``deg``: stored in radians, written in degrees).
FIELDS = (("SourceToIsocenterDistance", False), ("SourceToDetectorDistance", False), ("SourceOffsetX", False),
          ("SourceOffsetY", False), ("ProjectionOffsetX", False), ("ProjectionOffsetY", False),
          ("InPlaneAngle", True), ("OutOfPlaneAngle", True))


def _wrap(angle: float) -> float:
    """An angle (rad) in [0, 2π), as RTK stores it."""
    return angle - 2.0 * math.pi * math.floor(angle / (2.0 * math.pi))


def zxy_matrix(x: float, y: float, z: float) -> np.ndarray:
    """ITK's Euler3DTransform rotation in ZXY order: Rz(z) @ Rx(x) @ Ry(y)."""
    cx, sx, cy, sy, cz, sz = math.cos(x), math.sin(x), math.cos(y), math.sin(y), math.cos(z), math.sin(z)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    return rz @ rx @ ry


def zxy_angles(m: np.ndarray) -> tuple[float, float, float]:
    """(x, y, z) of :func:`zxy_matrix` from a rotation, as ITK extracts them (ComputeZYX off)."""
    x = math.asin(max(-1.0, min(1.0, m[2, 1])))
    a = math.cos(x)
    if abs(a) > 0.00005:
        y = math.atan2(-m[2, 0] / a, m[2, 2] / a)
        z = math.atan2(-m[0, 1] / a, m[1, 1] / a)
    else:
        z, y = 0.0, math.atan2(m[1, 0], m[0, 0])
    return x, y, z


def stable_zxy_angles(m: np.ndarray) -> tuple[float, float, float]:
    """:func:`zxy_angles`, checked by rebuilding the matrix; where that fails (near x = ±90°), the other branch
    of x, then the gimbal-lock choice z = 0 (as RTK falls back); :class:`SweepError` when none rebuilds ``m``."""
    def rebuilds(angles) -> bool:
        return bool(np.all(np.isfinite(angles))) and np.abs(zxy_matrix(*angles) - m).max() <= ANGLE_CHECK_TOLERANCE

    angles = zxy_angles(m)
    if rebuilds(angles):
        return angles
    if abs(abs(m[2, 1]) - 1.0) > GIMBAL_TOLERANCE:
        first = math.asin(max(-1.0, min(1.0, m[2, 1])))
        for x in (first, math.pi - first):
            cx = math.cos(x)
            angles = (x, math.atan2(-m[2, 0] / cx, m[2, 2] / cx), math.atan2(-m[0, 1] / cx, m[1, 1] / cx))
            if rebuilds(angles):
                return angles
    else:
        angles = (math.copysign(math.pi / 2, m[2, 1]), math.atan2(m[0, 2], m[0, 0]), 0.0)
        if rebuilds(angles):
            return angles
    raise SweepError("the detector orientation has no ZXY Euler angles that rebuild it (RTK would refuse it)")


def projection_parameters(source, detector, row, column) -> dict[str, float]:
    """RTK's parameters of one projection (``AddProjection(S, R, r, c)``): angles in rad wrapped to [0, 2π),
    lengths in the world unit of the arguments. :class:`SweepError` for non-orthogonal r, c or angles RTK could
    not represent either."""
    S, R, r, c = (np.asarray(a, dtype=float) for a in (source, detector, row, column))
    if abs(r @ c) > ORTHOGONALITY_TOLERANCE:
        raise SweepError(f"RTK needs orthogonal detector rows and columns, got r.c = {r @ c:.3g}")
    n = np.cross(r, c)
    oa, ga, ia = stable_zxy_angles(np.array([r, c, n]))
    sdd = float(n @ (S - R))
    return {"GantryAngle": _wrap(-ga), "OutOfPlaneAngle": _wrap(-oa), "InPlaneAngle": _wrap(-ia),
            "SourceToIsocenterDistance": float(n @ S), "SourceToDetectorDistance": 0.0 if abs(sdd) < 1e-6 else sdd,
            "SourceOffsetX": float(S @ r), "SourceOffsetY": float(S @ c),
            "ProjectionOffsetX": float(R @ r), "ProjectionOffsetY": float(R @ c)}


def projection_matrix(p: dict[str, float]) -> np.ndarray:
    """RTK's 3x4 matrix of a projection: projection translation · magnification · source translation · rotation."""
    translation = np.eye(3)
    translation[:2, 2] = (p["SourceOffsetX"] - p["ProjectionOffsetX"], p["SourceOffsetY"] - p["ProjectionOffsetY"])
    sdd, sid = -p["SourceToDetectorDistance"], -p["SourceToIsocenterDistance"]
    magnification = np.zeros((3, 4))
    if sdd == 0.0:  # parallel beam
        magnification[0, 0] = magnification[1, 1] = 1.0
        magnification[2, 3] = 1.0
    else:
        magnification[0, 0] = magnification[1, 1] = sdd
        magnification[2, 2], magnification[2, 3] = 1.0, sid
    source = np.eye(4)
    source[:2, 3] = (-p["SourceOffsetX"], -p["SourceOffsetY"])
    rotation = np.eye(4)
    rotation[:3, :3] = zxy_matrix(-p["OutOfPlaneAngle"], -p["GantryAngle"], -p["InPlaneAngle"])
    return translation @ magnification @ source @ rotation


def _number(value: float) -> str:
    """A double as C++ streams write it with precision 15 (``%.15g``)."""
    return f"{value:.15g}"


def xml_text(parameters: list[dict[str, float]]) -> str:
    """The file's text for the projections' parameters (:func:`projection_parameters`), as RTK's writer has it."""
    if not parameters:
        raise SweepError("an RTK geometry needs at least one projection")
    degrees = 180.0 / math.pi
    lines = ['<?xml version="1.0"?>', "<!DOCTYPE RTKGEOMETRY>", f'<RTKThreeDCircularGeometry version="{VERSION}">']
    shared = set()
    for name, in_degrees in FIELDS:
        values = [p[name] for p in parameters]
        if all(v == values[0] for v in values):
            shared.add(name)
            if values[0] != 0.0:
                lines.append(f"    <{name}>{_number(values[0] * (degrees if in_degrees else 1.0))}</{name}>")
    for p in parameters:
        lines.append("  <Projection>")
        lines.append(f"    <GantryAngle>{_number(p['GantryAngle'] * degrees)}</GantryAngle>")
        for name, in_degrees in FIELDS:
            if name not in shared:
                lines.append(f"    <{name}>{_number(p[name] * (degrees if in_degrees else 1.0))}</{name}>")
        lines.append("    <Matrix>")
        for row in projection_matrix(p):
            lines.append("      " + " ".join(f"{_number(v):>19}" for v in row))
        lines.append("    </Matrix>")
        lines.append("  </Projection>")
    lines.append("</RTKThreeDCircularGeometry>")
    return "\n".join(lines) + "\n"


def write(path, sources, detectors, rows, columns) -> Path:
    """Write RTK's XML for frames (n, 3) each: source, detector centre, unit row and column directions."""
    parameters = [projection_parameters(*frame) for frame in zip(sources, detectors, rows, columns)]
    path = Path(path)
    path.write_text(xml_text(parameters), encoding="utf-8")
    return path
