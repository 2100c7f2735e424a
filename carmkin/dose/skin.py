"""Skin cells: points on the patient's surface with outward normals and areas, in the table frame (m).

- :func:`from_patient`: the parametric body (:class:`carmkin.patient.ParametricPatient`): its trunk box's faces
  and its capsules' cylinders and hemispheres sampled at ``spacing``; a cell inside another segment (where two
  segments overlap) is not skin and is dropped.
- :func:`from_surface`: a closed triangle surface (a CT's skin, :func:`from_ct`): one cell per vertex that a
  triangle uses, its normal the area-weighted mean of its triangles' normals, turned outward (the surface's
  signed volume positive); the cells are the surface's vertices, whatever ``spacing``.
- :func:`plane` and :func:`cylinder`: PySkinDose's simple phantoms (a flat sheet, an elliptic cylinder), placed
  on the system's table top the way PySkinDose places them on its table: head end at the top's head end,
  centred across it, on a pad of ``pad`` m.

A cell is hit by a beam when it lies in the beam's pyramid and faces the source (``normal · (cell − source)
< 0``, PySkinDose's entrance test); a :func:`plane` is two-sided (PySkinDose does not test its facing either).
Cells shadowed by another part of the body (an arm over the trunk) are not removed: the entrance test is
per cell, as in PySkinDose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import DoseError
from carmkin.validation import real_scalar

#: Default spacing (m) of the skin cells.
DEFAULT_SPACING = 0.01
#: Finest and coarsest spacing accepted (m).
SPACING_RANGE = (0.001, 0.1)


@dataclass(frozen=True)
class Skin:
    """``points`` (N, 3) and outward unit ``normals`` (N, 3) in the table frame (m); ``two_sided``: every cell
    in the beam counts (a sheet), else only those facing the source; ``faces`` (F, 3): the triangles joining the
    cells when they are a surface's vertices (:func:`from_surface`), else None."""

    points: np.ndarray
    normals: np.ndarray
    two_sided: bool = False
    name: str = "skin"
    faces: np.ndarray | None = None


def _spacing(spacing) -> float:
    return real_scalar(spacing, "spacing", error=DoseError, low=SPACING_RANGE[0], high=SPACING_RANGE[1], unit="m")


def _top_head(system, pad: float) -> tuple[float, float]:
    """(y of the pad's upper surface, z of the table top's head end), table frame (Y0 down, Z0 to the head)."""
    t = system.table
    return t.top_center[1] - t.top_size[1] / 2 - pad, t.top_center[2] + t.top_size[2] / 2


def plane(system, width: float = 0.40, length: float = 1.20, spacing: float = DEFAULT_SPACING,
          pad: float = 0.04) -> Skin:
    """PySkinDose's plane phantom (default 40 × 120 cm, its ``plane_width`` / ``plane_length``) on the table top:
    across X0 centred, from the head end along −Z0, on a pad of ``pad`` m (PySkinDose's 4 cm)."""
    h = _spacing(spacing)
    width = real_scalar(width, "width", error=DoseError, low=h, high=5.0, unit="m")
    length = real_scalar(length, "length", error=DoseError, low=h, high=5.0, unit="m")
    pad = real_scalar(pad, "pad", error=DoseError, low=0.0, high=0.5, unit="m")
    y, z0 = _top_head(system, pad)
    xs = np.linspace(-width / 2, width / 2, int(round(width / h)) + 1)
    zs = z0 - np.linspace(0.0, length, int(round(length / h)) + 1)
    X, Z = np.meshgrid(xs, zs)
    points = np.column_stack((X.ravel(), np.full(X.size, y), Z.ravel()))
    normals = np.tile([0.0, -1.0, 0.0], (len(points), 1))
    return Skin(points, normals, two_sided=True, name="plane")


def cylinder(system, a: float = 0.20, b: float = 0.10, length: float = 1.50, spacing: float = DEFAULT_SPACING,
             pad: float = 0.04) -> Skin:
    """PySkinDose's elliptic cylinder phantom (semi-axes ``a`` across, ``b`` up; default 20 × 10 cm, 150 cm
    long) lying on the pad on the table top, from the head end along −Z0."""
    h = _spacing(spacing)
    a = real_scalar(a, "a", error=DoseError, low=0.01, high=1.0, unit="m")
    b = real_scalar(b, "b", error=DoseError, low=0.01, high=1.0, unit="m")
    length = real_scalar(length, "length", error=DoseError, low=h, high=5.0, unit="m")
    pad = real_scalar(pad, "pad", error=DoseError, low=0.0, high=0.5, unit="m")
    y0, z0 = _top_head(system, pad)
    perimeter = math.pi * (3 * (a + b) - math.sqrt((3 * a + b) * (a + 3 * b)))  # Ramanujan
    t = np.linspace(0.0, 2 * math.pi, max(8, int(round(perimeter / h))), endpoint=False)
    zs = z0 - np.linspace(0.0, length, int(round(length / h)) + 1)
    T, Z = np.meshgrid(t, zs)
    T, Z = T.ravel(), Z.ravel()
    points = np.column_stack((a * np.cos(T), y0 - b - b * np.sin(T), Z))  # Y0 down: the top at y0 - 2b
    normals = np.column_stack((b * np.cos(T), -a * np.sin(T), np.zeros_like(T)))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    return Skin(points, normals, name="cylinder")


def _box_cells(extents, h: float):
    half = np.asarray(extents) / 2
    points, normals = [], []
    for axis in range(3):
        others = [i for i in range(3) if i != axis]
        grids = [np.linspace(-half[i], half[i], max(2, int(round(2 * half[i] / h)) + 1)) for i in others]
        A, B = np.meshgrid(*grids)
        for sign in (-1.0, 1.0):
            p = np.zeros((A.size, 3))
            p[:, others[0]], p[:, others[1]], p[:, axis] = A.ravel(), B.ravel(), sign * half[axis]
            n = np.zeros_like(p)
            n[:, axis] = sign
            points.append(p)
            normals.append(n)
    return np.vstack(points), np.vstack(normals)


def _capsule_cells(a, b, r: float, h: float):
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = float(np.linalg.norm(axis))
    axis = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    n_round = max(8, int(round(2 * math.pi * r / h)))
    phi = np.linspace(0.0, 2 * math.pi, n_round, endpoint=False)
    ring = np.outer(np.cos(phi), e1) + np.outer(np.sin(phi), e2)
    points, normals = [], []
    for s in np.linspace(0.0, length, max(2, int(round(length / h)) + 1)):
        points.append(a + s * axis + r * ring)
        normals.append(ring)
    for end, sign in ((a, -1.0), (b, 1.0)):  # hemispheres: rings of latitude
        for theta in np.linspace(0.0, math.pi / 2, max(2, int(round(math.pi / 2 * r / h)) + 1))[1:]:
            k = max(1, int(round(n_round * math.cos(theta))))
            ph = np.linspace(0.0, 2 * math.pi, k, endpoint=False)
            n = (math.cos(theta) * (np.outer(np.cos(ph), e1) + np.outer(np.sin(ph), e2))
                 + sign * math.sin(theta) * axis)
            points.append(end + r * n)
            normals.append(n)
    return np.vstack(points), np.vstack(normals)


def _inside(segment, points: np.ndarray, margin: float) -> np.ndarray:
    if segment.shape == "box":
        return np.all(np.abs(points - np.asarray(segment.a)) < np.asarray(segment.extents) / 2 - margin, axis=1)
    a, b = np.asarray(segment.a), np.asarray(segment.b)
    ab = b - a
    t = np.clip((points - a) @ ab / max(float(ab @ ab), 1e-30), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1) < segment.radius - margin


def from_patient(patient, spacing: float = DEFAULT_SPACING) -> Skin:
    """Skin cells of a :class:`carmkin.patient.ParametricPatient`, table frame (m)."""
    from carmkin.patient import ParametricPatient

    if not isinstance(patient, ParametricPatient):
        raise DoseError(f"patient must be a carmkin.patient.ParametricPatient, a CTPatient or a carmkin.dose Skin, got "
                        f"{type(patient).__name__}")
    h = _spacing(spacing)
    parts = []
    for segment in patient.segments:
        if segment.shape == "box":
            p, n = _box_cells(segment.extents, h)
            p = p + np.asarray(segment.a)
        else:
            p, n = _capsule_cells(segment.a, segment.b, segment.radius, h)
        keep = np.ones(len(p), bool)
        for other in patient.segments:
            if other is not segment:
                keep &= ~_inside(other, p, 1e-9)
        parts.append((p[keep], n[keep]))
    T = patient.pose()
    points = np.vstack([p for p, _ in parts]) @ T[:3, :3].T + T[:3, 3]
    normals = np.vstack([n for _, n in parts]) @ T[:3, :3].T
    return Skin(points, normals, name="parametric patient")


def from_surface(vertices, faces, name: str = "surface") -> Skin:
    """Skin cells of a closed triangle surface: ``vertices`` (N, 3) m (table frame) and ``faces`` (F, 3) vertex
    indices; a vertex no triangle uses is not skin; a vertex whose triangles' normals cancel is refused."""
    from carmkin.validation import real_array

    vertices = real_array(vertices, "vertices", (None, 3), error=DoseError, unit="m")
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or not len(faces) or not np.issubdtype(faces.dtype, np.integer):
        raise DoseError(f"faces must be (F, 3) integer vertex indices, F >= 1, got {faces.dtype} of shape "
                        f"{faces.shape}")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise DoseError(f"faces must index the {len(vertices)} vertices, got indices {faces.min()}..{faces.max()}")
    edges = np.sort(np.vstack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    if np.any(counts != 2):
        raise DoseError(f"faces must close the surface (every edge in two triangles): {int(np.sum(counts != 2))} of "
                        f"its {len(counts)} edges are not")
    directed = np.vstack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    if len(np.unique(directed, axis=0)) != len(directed):  # two triangles run an edge the same way: one is flipped
        raise DoseError("faces must be wound consistently (each edge run once each way)")
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    area_normals = np.cross(b - a, c - a) / 2  # |.| = the triangle's area, counter-clockwise winding
    o = a.mean(axis=0)  # about a point near the surface: less round-off
    volume = float(np.einsum("ij,ij->i", a - o, np.cross(b - o, c - o)).sum()) / 6.0
    if volume == 0.0:  # divergence theorem: positive when the winding is outward
        raise DoseError("faces must enclose a volume, got a flat surface")
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, faces[:, k], area_normals)
    used = np.zeros(len(vertices), bool)
    used[faces.ravel()] = True
    length = np.linalg.norm(normals, axis=1)
    flat = used & (length == 0.0)
    if flat.any():
        raise DoseError(f"faces leave {int(flat.sum())} vertices without a normal (their triangles' normals cancel), "
                        f"e.g. vertex {int(np.flatnonzero(flat)[0])}")
    normals = np.sign(volume) * normals[used] / length[used][:, None]
    index = np.cumsum(used) - 1  # a kept vertex's cell
    return Skin(vertices[used].copy(), normals, name=name, faces=index[faces])


def from_ct(patient) -> Skin:
    """Skin cells of a :class:`carmkin.patient.CTPatient` (:meth:`~carmkin.patient.CTPatient.from_ct`, placed with
    ``on_table``): its marching-cubes surface (:func:`from_surface`) in the table frame."""
    from carmkin.patient import CTPatient

    if not isinstance(patient, CTPatient):
        raise DoseError(f"patient must be a carmkin.patient.CTPatient, got {type(patient).__name__}")
    if patient.faces is None:
        raise DoseError("the CT patient has no surface triangles (faces=None): build it with CTPatient.from_ct")
    return from_surface(patient.surface(), patient.faces, name="CT surface")


def skin_of(patient, spacing: float = DEFAULT_SPACING) -> Skin:
    """``patient`` as skin cells: a :class:`Skin` as it is, a parametric patient sampled at ``spacing``, a CT patient's
    surface (:func:`from_ct`; its vertices, whatever ``spacing``)."""
    from carmkin.patient import CTPatient

    if isinstance(patient, Skin):
        return patient
    if isinstance(patient, CTPatient):
        return from_ct(patient)
    return from_patient(patient, spacing)
