"""Anatomy for the views: vessel centrelines (with radii), valve planes, and centrelines from a CT label volume.

Every object here lives in the **table frame 0, metres** (as the views do). Anatomy measured in the patient
(DICOM LPS, mm: a CT, a planning tool's export) is placed by :func:`patient_to_table`: the patient frame's
pose in the table frame (a Patient Position code, a 4×4 pose, or a patient model's ``pose()``) times an
optional measured rotation of the patient about its own origin (the CT's patient frame vs the patient as it
lies on the table). A CT label volume is skeletonized (scikit-image) in the CT's voxel grid and placed through
the same CT-to-table transform as :class:`carmkin.patient.CTPatient` (:meth:`carmkin.interop.drr.Volume.in_table`:
RAS → LPS, the volume's centre at the patient origin).

Bad input is refused with :class:`~carmkin.errors.CentrelineError`, :class:`~carmkin.errors.PlaneError` or
:class:`~carmkin.errors.AnatomyPlacementError`, naming the argument and the expected units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.errors import AnatomyPlacementError, CentrelineError, PlaneError
from carmkin.validation import integer, real_array

#: Shortest segment (m) between consecutive centreline points: closer points are a repeated point.
MIN_SEGMENT = 1e-6
#: Shortest and longest plausible centreline arc length (m): outside, the units are wrong (mm read as m or
#: m read as mm); the longest vessel a view targets (aorta, iliac) is well under 1 m.
MIN_LENGTH = 1e-3
MAX_LENGTH = 1.0
#: Largest plausible vessel radius (m) (the aortic root is ~15 mm).
MAX_RADIUS = 0.03
#: Most vessels and most points per vessel of :func:`synthetic_tree` (a coronary tree has tens of named
#: segments; 10**30 was accepted and hung).
MAX_TREE_VESSELS = 1000
MAX_TREE_POINTS = 100_000
#: Relative size (second over first singular value of the centred points) below which plane points are
#: collinear (or coincident).
COLLINEAR_TOLERANCE = 1e-6


@dataclass(frozen=True)
class Centreline:
    """A vessel: ``points`` (N, 3) m in the table frame (N ≥ 2, consecutive points at least
    :data:`MIN_SEGMENT` apart), ``radii`` (N,) m or ``None`` (the map's default), ``name`` for messages."""

    points: np.ndarray
    radii: np.ndarray | None = None
    name: str = "centreline"

    def __post_init__(self) -> None:
        name = self.name if isinstance(self.name, str) and self.name else "centreline"
        object.__setattr__(self, "name", name)
        points = real_array(self.points, name, (None, 3), error=CentrelineError, unit="m, table frame")
        if len(points) < 2:
            raise CentrelineError(f"{name} must have at least 2 points (N, 3) in m, got {len(points)}")
        step = np.linalg.norm(np.diff(points, axis=0), axis=1)
        if np.any(step < MIN_SEGMENT):
            k = int(np.argmax(step < MIN_SEGMENT))
            raise CentrelineError(f"{name}: points {k} and {k + 1} repeat {points[k].tolist()} (a segment of zero "
                                  f"length, under {MIN_SEGMENT * 1e3:g} mm): remove the repeated point")
        unique, first = np.unique(points, axis=0, return_index=True)
        if len(unique) < len(points):
            k = int(np.setdiff1d(np.arange(len(points)), first)[0])
            raise CentrelineError(f"{name}: point {k} repeats an earlier point {points[k].tolist()} (m): a centreline "
                                  "visits each point once")
        length = float(step.sum())
        if not MIN_LENGTH <= length <= MAX_LENGTH:
            raise CentrelineError(f"{name} is {length:.6g} m long: expected {MIN_LENGTH:g}..{MAX_LENGTH:g} m (table "
                                  "frame, metres; were millimetres given as metres, or the reverse?)")
        points.setflags(write=False)
        object.__setattr__(self, "points", points)
        if self.radii is not None:
            radii = real_array(self.radii, f"{name} radii", (len(points),), error=CentrelineError, unit="m")
            if np.any(radii < 0) or np.any(radii > MAX_RADIUS):
                raise CentrelineError(f"{name} radii must lie in [0, {MAX_RADIUS:g}] m, got "
                                      f"{radii.min():g}..{radii.max():g}")
            radii.setflags(write=False)
            object.__setattr__(self, "radii", radii)

    @property
    def length(self) -> float:
        """3D arc length (m)."""
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())

    @property
    def midpoint(self) -> np.ndarray:
        """The point halfway along the arc (m, table frame): the map's default target."""
        step = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
        s = np.concatenate(([0.0], np.cumsum(step)))
        half = s[-1] / 2
        k = min(int(np.searchsorted(s, half, side="right")) - 1, len(step) - 1)
        t = (half - s[k]) / step[k]
        return self.points[k] + t * (self.points[k + 1] - self.points[k])


def as_centreline(value, name: str = "centreline", radii=None) -> Centreline:
    """``value`` (a :class:`Centreline` or points (N, 3) m, table frame) as a :class:`Centreline`."""
    if isinstance(value, Centreline):
        return value
    return Centreline(value, radii, name)


@dataclass(frozen=True)
class Plane:
    """A plane fitted (least squares) to ``points`` (K, 3) m (table frame; e.g. the three aortic cusp nadirs):
    ``centre`` (3,) their mean, ``normal`` (3,) unit."""

    points: np.ndarray
    centre: np.ndarray
    normal: np.ndarray


def plane_from_points(points, name: str = "plane points") -> Plane:
    """The least-squares plane of ≥ 3 points (K, 3) m, table frame (SVD of the centred points); collinear or
    coincident points raise :class:`~carmkin.errors.PlaneError`."""
    P = real_array(points, name, (None, 3), error=PlaneError, unit="m, table frame")
    if len(P) < 3:
        raise PlaneError(f"{name} must hold at least 3 points (K, 3) in m, got {len(P)}")
    centre = P.mean(axis=0)
    _, sv, Vt = np.linalg.svd(P - centre)
    if sv[0] < MIN_SEGMENT or sv[1] < COLLINEAR_TOLERANCE * sv[0]:
        raise PlaneError(f"{name} are collinear or coincident (singular values {sv[0]:.3g}, {sv[1]:.3g} m): "
                         "a plane needs 3 points not on one line")
    normal = Vt[2] / np.linalg.norm(Vt[2])
    return Plane(P, centre, normal)


def patient_to_table(patient="HFS", rotation=None) -> np.ndarray:
    """Pose (4, 4) taking patient LPS coordinates (m) to the table frame: the patient frame's pose (a
    Patient Position code, a 4×4 pose, or a patient model with ``pose()``) times ``rotation`` (3, 3), a
    measured rotation of the patient about its own origin (LPS axes; ``None``: none)."""
    from carmkin.transforms import check_rigid_transform

    from .view import _patient_frame

    T = np.array(_patient_frame(patient), dtype=float)
    if rotation is not None:
        R = real_array(rotation, "rotation", (3, 3), error=AnatomyPlacementError)
        check_rigid_transform(np.block([[R, np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]]), "rotation")
        T[:3, :3] = T[:3, :3] @ R
    return T


def centreline_from_patient(points_mm, patient="HFS", radii_mm=None, name: str = "centreline",
                            rotation=None) -> Centreline:
    """A centreline measured in the patient frame (LPS, **mm**, e.g. a CT segmentation's export) placed in the
    table frame (m) by :func:`patient_to_table`."""
    P = real_array(points_mm, name, (None, 3), error=CentrelineError, unit="mm, patient LPS")
    T = patient_to_table(patient, rotation)
    radii = None if radii_mm is None else real_array(radii_mm, f"{name} radii", error=CentrelineError, unit="mm") / 1e3
    return Centreline(P / 1e3 @ T[:3, :3].T + T[:3, 3], radii, name)


def skeleton_centreline(labels, affine, patient="HFS", origin=(0.0, 0.0, 0.0), *, label: int | None = None,
                        name: str = "centreline", rotation=None) -> Centreline:
    """The centreline of a labelled vessel in a CT label volume ``labels`` (I, J, K) with its NIfTI
    ``affine`` (4, 4, voxel → RAS mm): the voxels of ``label`` (default: every non-zero voxel) skeletonized
    (``skimage.morphology.skeletonize``), the skeleton's longest path (in 26-connected voxel steps) ordered
    from one end to the other, placed in the table frame as the CT patient is (``patient``: a
    :class:`~carmkin.patient.CTPatient` — its position and origin —, or a Patient Position code with
    ``origin`` (3,) m; ``rotation`` as in :func:`patient_to_table`)."""
    from carmkin.extras import require
    from carmkin.interop.drr import Volume

    morphology = require("skimage.morphology", "ct")
    volume = real_array(labels, "labels", (None, None, None), error=CentrelineError)
    A = real_array(affine, "affine", (4, 4), error=CentrelineError, unit="mm")
    mask = volume != 0 if label is None else volume == label
    if not mask.any():
        raise CentrelineError(f"labels hold no voxel of label {label if label is not None else '!= 0'}")
    if hasattr(patient, "position") and hasattr(patient, "origin"):
        patient, origin = patient.position, patient.origin
    skeleton = np.argwhere(morphology.skeletonize(mask))
    path = skeleton[_longest_path(skeleton)]
    world_mm = path @ A[:3, :3].T + A[:3, 3]
    T = Volume(mask, A).in_table(patient_to_table(patient_pose_of(patient, origin), rotation))
    return Centreline(world_mm / 1e3 @ T[:3, :3].T + T[:3, 3], None, name)


def centreline_from_ct(points_mm, shape, affine, patient="HFS", origin=(0.0, 0.0, 0.0), *, radii_mm=None,
                       name: str = "centreline", rotation=None) -> Centreline:
    """A centreline given in a CT's world (NIfTI RAS, **mm**; e.g. picked on the CT) placed in the table frame
    as the CT patient is (``patient``: a :class:`~carmkin.patient.CTPatient` or a Patient Position code with
    ``origin`` (3,) m; ``rotation`` as in :func:`patient_to_table`); the CT is ``shape`` (I, J, K) voxels with
    ``affine`` (4, 4, voxel → RAS mm). Points outside the volume raise
    :class:`~carmkin.errors.AnatomyPlacementError`."""
    from carmkin.interop.drr import Volume

    P = real_array(points_mm, name, (None, 3), error=CentrelineError, unit="mm, CT world (RAS)")
    A = real_array(affine, "affine", (4, 4), error=CentrelineError, unit="mm")
    check_inside_ct(P, shape, A, name)
    if hasattr(patient, "position") and hasattr(patient, "origin"):
        patient, origin = patient.position, patient.origin
    T = Volume(np.zeros(tuple(int(n) for n in shape), dtype=np.uint8), A).in_table(
        patient_to_table(patient_pose_of(patient, origin), rotation))
    radii = None if radii_mm is None else real_array(radii_mm, f"{name} radii", error=CentrelineError, unit="mm") / 1e3
    return Centreline(P / 1e3 @ T[:3, :3].T + T[:3, 3], radii, name)


def patient_pose_of(position, origin) -> np.ndarray:
    """The patient frame's pose (4, 4): a Patient Position code at ``origin`` (3,) m, or a pose as given."""
    from carmkin.imaging.projection import patient_pose

    return patient_pose(position, origin) if isinstance(position, str) else np.asarray(position, dtype=float)


def _longest_path(voxels: np.ndarray) -> np.ndarray:
    """Indices into ``voxels`` (n, 3) of the longest shortest path (26-neighbour steps, Euclidean weights)
    between two skeleton voxels: two Dijkstra sweeps (farthest from any voxel, then farthest from that)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    if len(voxels) < 2:
        raise CentrelineError(f"the skeleton has {len(voxels)} voxel: too small a vessel for a centreline")
    index = {tuple(v): k for k, v in enumerate(voxels.tolist())}
    rows, cols, weights = [], [], []
    offsets = [np.array(o) for o in np.ndindex(3, 3, 3) if o != (1, 1, 1)]
    for k, v in enumerate(voxels):
        for o in offsets:
            j = index.get(tuple((v + o - 1).tolist()))
            if j is not None:
                rows.append(k), cols.append(j), weights.append(float(np.linalg.norm(o - 1)))
    graph = coo_matrix((weights, (rows, cols)), shape=(len(voxels),) * 2).tocsr()
    first = dijkstra(graph, indices=0)
    a = int(np.argmax(np.where(np.isfinite(first), first, -1)))
    dist, pred = dijkstra(graph, indices=a, return_predecessors=True)
    b = int(np.argmax(np.where(np.isfinite(dist), dist, -1)))
    path = [b]
    while path[-1] != a:
        path.append(int(pred[path[-1]]))
    return np.array(path[::-1])


def check_inside_ct(points_mm, shape, affine, name: str = "centreline") -> None:
    """Refuse points (N, 3) RAS mm outside the CT volume of ``shape`` (I, J, K) and ``affine`` (voxel → mm)."""
    P = real_array(points_mm, name, (None, 3), error=CentrelineError, unit="mm")
    index = (np.linalg.inv(np.asarray(affine, dtype=float)) @ np.column_stack((P, np.ones(len(P)))).T)[:3].T
    outside = np.any((index < -0.5) | (index > np.asarray(shape) - 0.5), axis=1)
    if outside.any():
        k = int(np.argmax(outside))
        raise AnatomyPlacementError(f"{name}: point {k} {P[k].tolist()} mm lies outside the CT volume "
                                    f"(voxel index {np.round(index[k], 1).tolist()}, shape {list(shape)})")


def check_inside_patient(points, patient, name: str = "centreline") -> None:
    """Refuse points (N, 3) m (table frame) outside every obstacle of a patient model (its boxes, capsules,
    spheres, cylinders: the body the anatomy belongs to)."""
    from carmkin.world.obstacles import as_obstacles

    P = np.asarray(points, dtype=float)
    inside = np.zeros(len(P), dtype=bool)
    for o in as_obstacles(patient):
        local = (P - o.pose[:3, 3]) @ o.pose[:3, :3]
        if o.shape == "box":
            inside |= np.all(np.abs(local) <= np.asarray(o.size) / 2, axis=1)
        elif o.shape == "sphere":
            inside |= np.linalg.norm(local, axis=1) <= o.size[0]
        else:
            r, half = o.size[0], o.size[1] / 2
            z = local[:, 2] if o.shape == "cylinder" else np.clip(local[:, 2], -half, half)
            radial = np.hypot(local[:, 0], local[:, 1]) if o.shape == "cylinder" else np.linalg.norm(
                local - np.column_stack((np.zeros_like(z), np.zeros_like(z), z)), axis=1)
            inside |= (radial <= r) & (np.abs(local[:, 2]) <= (half if o.shape == "cylinder" else half + r))
    if not inside.all():
        k = int(np.argmin(inside))
        raise AnatomyPlacementError(f"{name}: point {k} {np.round(P[k] * 1e3, 1).tolist()} mm (table frame) lies "
                                    "outside the patient: place the anatomy in the patient's frame "
                                    "(centreline_from_patient) or check its units")


#: Radius (m) of the synthetic heart the coronary trees of :func:`synthetic_tree` wind around.
HEART_RADIUS = 0.05


def synthetic_tree(centre, seed: int = 0, vessels: int = 4, points: int = 40) -> list[Centreline]:
    """A synthetic coronary tree: ``vessels`` helical segments (each 40–110 mm, ``points`` points) on a
    sphere of :data:`HEART_RADIUS` about ``centre`` (3,) m, table frame — polar and azimuthal angles linear in
    the arc parameter, so each winds around the heart like an epicardial artery. The first is the vessel of
    interest, the others overlap it in some views. Deterministic in ``seed`` (an integer ≥ 0: ``None`` would
    draw fresh entropy); ``vessels`` 1 … :data:`MAX_TREE_VESSELS`, ``points`` 2 … :data:`MAX_TREE_POINTS`."""
    centre = real_array(centre, "centre", (3,), error=CentrelineError, unit="m")
    seed = integer(seed, "seed", low=0, error=CentrelineError)
    vessels = integer(vessels, "vessels", low=1, high=MAX_TREE_VESSELS, error=CentrelineError)
    points = integer(points, "points", low=2, high=MAX_TREE_POINTS, error=CentrelineError)
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, points)[:, None]
    out = []
    for k in range(vessels):
        theta = rng.uniform(0.5, 1.2) + rng.uniform(0.4, 1.2) * t * rng.choice([-1, 1])
        phi = rng.uniform(0, 2 * np.pi) + rng.uniform(0.5, 1.6) * t * rng.choice([-1, 1])
        radius = HEART_RADIUS * (1.0 + 0.1 * rng.uniform(-1, 1))
        xyz = np.hstack((np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)))
        out.append(Centreline(centre + radius * xyz, None, "vessel of interest" if k == 0 else f"vessel {k}"))
    return out
