"""A planned sweep's geometry in the conventions of RTK, ASTRA, TIGRE and DICOM (docs/sweeps.md draws them).

Our frame k (:class:`~carmkin.sweeps.plan.Sweep`): source pose ``T_k`` in the table frame 0 (x along image
columns, y along rows (down), z the principal axis), SDD ``f``, pixel pitch ``(sx, sy)``, principal point
``(u0, v0)`` px, pixel centres at integer (column, row); ``P_k = K [R_kᵀ | −R_kᵀ s_k]`` maps table-frame m to
px. Exports express the world in **mm** (the packages' usual unit; ``scale`` changes it), table axes kept.

* **RTK** (``ThreeDCircularProjectionGeometry``): per frame ``AddProjection(source, detector, u, v)``
  with the detector point = the principal point's foot ``s + f z`` and the detector axes of a layout
  (:data:`RTK_LAYOUTS`; ``"image"``: u = x, v = y). ``GetMatrix(i)`` then maps world mm to *detector
  physical* mm ``(u, v)`` measured from that foot: pixel (c, r) sits where
  ``(c − u0) sx x + (r − v0) sy y = u·u_dir + v·v_dir`` (:func:`pixel_from_detector`); the projection
  stack's origin and spacing are :func:`rtk_projection_grid` (``"image"``: spacing ``(sx, sy, 1)`` mm,
  origin ``(−u0 sx, −v0 sy, 0)`` mm).
* **ASTRA** ``cone_vec``: rows ``(src, d, u, v)``: the source, the centre of the detector array (pixel
  coordinate ((cols − 1)/2, (rows − 1)/2)), u = the step of one column, v = of one row. Data layout
  (rows, angles, cols); ASTRA's column/row = ours.
* **TIGRE** arbitrary geometry (``geo.DSD``, ``geo.DSO``, ``geo.angles`` (n, 3) ZYZ Euler,
  ``geo.offOrigin`` (n, 3) in TIGRE's Python order (z, y, x), ``geo.offDetector`` (n, 2) (v, u),
  ``geo.rotDetector`` zeros, following TIGRE's ``computeDeltas_Siddon``): the image (volume) frame has the
  table axes with its centre at ``volume_centre``. TIGRE's detector is left-handed seen from our pinhole
  (column along +y, row along +z of its local frame, beam along −x): TIGRE projection row ``v`` is our row
  ``rows − 1 − v`` (flip the rows, ``proj[:, ::-1, :]``); columns agree.
* **DICOM**: per-frame XA Positioner Primary/Secondary Angle and detector rotation
  (:func:`carmkin.interop.dicom.xa_angles`).
"""

from __future__ import annotations

import math

import numpy as np

from carmkin.errors import SweepError

#: World units per metre of the exports (mm).
MM = 1e3


def feasible(sweep, geometry_only: bool = False):
    """``sweep`` when it is a planned :class:`~carmkin.sweeps.Sweep` that succeeded; else :class:`SweepError`: a
    failed sweep's frames include poses the machine cannot take (joints out of range, contacts), so its geometry
    is never exported (``sweep.cut()`` plans its largest feasible arc). ``geometry_only``: the frames as an
    assumed geometry whatever the machine can do (a reconstruction study's ideal circle), never a plan to run."""
    from .plan import Sweep

    from carmkin.validation import flag

    if not isinstance(sweep, Sweep):
        raise SweepError(f"sweep must be a carmkin.sweeps.Sweep (plan_sweep(...)), got {type(sweep).__name__}")
    geometry_only = flag(geometry_only, "geometry_only", error=SweepError)
    if not sweep.success and not geometry_only:
        raise SweepError(f"sweep: a failed sweep is not exported ({sweep.failure}); sweep.cut() plans its largest "
                         "feasible arc")
    return sweep


def _scale(scale) -> float:
    """``scale`` (world units per metre) as a positive finite float, or :class:`SweepError` naming it."""
    from carmkin.validation import real_scalar

    scale = real_scalar(scale, "scale", error=SweepError, low=1e-12, unit="world units per m")
    if not scale > 0:
        raise SweepError(f"scale must be > 0 (world units per m; 1000 for mm), got {scale!r}")
    return scale


def _frames(sweep, geometry_only: bool = False):
    """Source positions s (n, 3) m, rotations R (n, 3, 3), SDD f (m), pitch (sx, sy) m, (u0, v0) px, size."""
    sweep = feasible(sweep, geometry_only)
    carm = sweep.system.carm
    K = carm.intrinsics()
    return (sweep.poses[:, :3, 3], sweep.poses[:, :3, :3], carm.source_to_detector, carm.pixel_spacing,
            (K[0, 2], K[1, 2]), (carm.detector_columns, carm.detector_rows))


def astra_vectors(sweep, scale: float = MM) -> np.ndarray:
    """ASTRA ``cone_vec`` rows (n, 12): source, detector centre, u (one column), v (one row); world units
    ``scale`` per metre (default mm)."""
    scale = _scale(scale)
    s, R, f, (sx, sy), (u0, v0), (cols, rows) = _frames(sweep)
    x, y, z = R[:, :, 0], R[:, :, 1], R[:, :, 2]
    centre = s + f * z + ((cols - 1) / 2 - u0) * sx * x + ((rows - 1) / 2 - v0) * sy * y
    return np.concatenate((s, centre, sx * x, sy * y), axis=1) * scale


def _zyz(M: np.ndarray) -> tuple[float, float, float]:
    """(α, θ, ψ) with ``M = Rz(α) Ry(θ) Rz(ψ)`` (TIGRE's ``eulerZYZ``)."""
    theta = math.atan2(math.hypot(M[0, 2], M[1, 2]), M[2, 2])
    if math.hypot(M[0, 2], M[1, 2]) < 1e-12:  # θ = 0 or π: only α ± ψ is defined; ψ = 0
        return math.atan2(M[1, 0], M[0, 0]) if M[2, 2] > 0 else math.atan2(-M[1, 0], -M[0, 0]), theta, 0.0
    return math.atan2(M[1, 2], M[0, 2]), theta, math.atan2(M[2, 1], -M[2, 0])


#: Our camera axes (columns x, y, z) in TIGRE's local detector frame, rows flipped: x = +y_T, y = −z_T, z = −x_T.
CAMERA_IN_TIGRE = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def tigre_geometry(sweep, volume_centre=None, scale: float = MM) -> dict:
    """TIGRE arbitrary-geometry arrays (world units ``scale`` per metre, default mm), keyed by the names of
    TIGRE's ``Geometry`` attributes: ``DSD``, ``DSO`` (n,), ``angles`` (n, 3), ``offOrigin`` (n, 3) (z, y, x),
    ``offDetector`` (n, 2) (v, u), ``rotDetector`` (n, 3), ``COR`` (n,), ``nDetector`` (rows, cols),
    ``dDetector`` (n/a, mm) (v, u). The image centre is ``volume_centre`` (3,) m in the table frame (default
    the sweep's target); image axes are the table axes. Our image = TIGRE's with its rows flipped."""
    scale = _scale(scale)
    s, R, f, (sx, sy), (u0, v0), (cols, rows) = _frames(sweep)
    from carmkin.validation import real_array

    c = sweep.target if volume_centre is None else real_array(volume_centre, "volume_centre", (3,), error=SweepError,
                                                               unit="m")
    z = R[:, :, 2]
    dso = np.einsum("ni,ni->n", c[None] - s, z)  # the rotation centre: the centre's foot on the principal axis
    if np.any(dso <= 0):
        raise SweepError("the volume centre is behind the source in some frame: TIGRE needs DSO > 0")
    angles = np.array([_zyz(Rk @ CAMERA_IN_TIGRE.T) for Rk in R])
    off_origin = c[None] - (s + dso[:, None] * z)  # image centre in TIGRE's world (its rotation centre at 0)
    off_u = ((cols - 1) / 2 - u0) * sx
    off_v = (v0 - (rows - 1) / 2) * sy
    n = len(R)
    return {
        "DSD": np.full(n, f * scale), "DSO": dso * scale, "angles": angles,
        "offOrigin": off_origin[:, ::-1] * scale, "offDetector": np.tile([off_v * scale, off_u * scale], (n, 1)),
        "rotDetector": np.zeros((n, 3)), "COR": np.zeros(n),
        "nDetector": np.array([rows, cols]), "dDetector": np.array([sy, sx]) * scale,
    }


def positioner_angles(sweep, patient="HFS") -> np.ndarray:
    """Per-frame XA positioner angles (n, 3) in degrees: primary (LAO +), secondary (CRA +) and the detector
    rotation about the beam, for a patient on the table (position code or LPS pose, see
    :func:`carmkin.interop.dicom.xa_angles`); the isocentre of each frame is the target at ``sweep.distance``."""
    from carmkin.interop.dicom import xa_angles

    return np.array([xa_angles(T, patient) for T in feasible(sweep).poses])


def _rtk():
    """``(itk, rtk)``, or :class:`~carmkin.errors.MissingExtraError` naming the ``cbct`` extra. Loading RTK's
    wrappers takes tens of seconds the first time in a process (ITK's lazy loading); SWIG's import-time
    DeprecationWarnings are silenced, and ITK's warning display is turned off: the one warning RTK gives
    here (Parker weights of a scan shorter than 180° + fan) is stated by :class:`~.plan.ShortScan`."""
    import warnings

    from carmkin.extras import require

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        itk = require("itk", "cbct")
        rtk = itk.RTK
        rtk.ThreeDCircularProjectionGeometry  # noqa: B018 (loads the wrappers inside the filter)
    itk.Object.GlobalWarningDisplayOff()
    return itk, rtk


#: RTK detector layouts: ``"image"`` (u = our x, v = our y: RTK's stack is our image; u × v points away from
#: the source, which RTK records as negative SID/SDD, a mirror) and ``"rotation"`` (v along the rotation
#: axis, u = z × v so that u × v points to the source as in RTK's circular convention: needed by its FDK
#: and Parker weights, which filter along u and read gantry angles about Y).
RTK_LAYOUTS = ("image", "rotation")


def rtk_detector_axes(sweep, layout: str = "image", geometry_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (u, v) of the RTK detector axes in our source frame for ``layout`` (:data:`RTK_LAYOUTS`)."""
    sweep = feasible(sweep, geometry_only)
    if not isinstance(layout, str) or layout not in RTK_LAYOUTS:
        raise SweepError(f"layout must be one of {', '.join(RTK_LAYOUTS)}, got {layout!r:.60}")
    if layout == "image":
        return np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    from .trajectory import rotation_axis

    mid = sweep.n_views // 2
    a = rotation_axis(sweep.system, sweep.q_plain[mid], sweep.weights)
    k = int(np.argmax(np.abs(a[:2])))
    if abs(a[k]) < 1.0 - 1e-9:
        raise SweepError("the rotation axis is not along an image axis: the 'rotation' layout would need resampling "
                         f"(axis in the source frame {np.round(a, 6).tolist()})")
    v = np.zeros(3)
    v[k] = math.copysign(1.0, a[k])
    return np.cross([0.0, 0.0, 1.0], v), v


def rtk_geometry(sweep, scale: float = MM, layout: str = "image", geometry_only: bool = False):
    """An ``rtk.ThreeDCircularProjectionGeometry`` with one ``AddProjection`` per frame (world units ``scale``
    per metre, default mm): source, the principal point's foot, and the detector axes of ``layout``."""
    scale = _scale(scale)
    itk, rtk = _rtk()
    sources, detectors, rows, columns = rtk_frames(sweep, scale, layout, geometry_only)
    geometry = rtk.ThreeDCircularProjectionGeometry.New()

    def point(a):
        p = itk.Point[itk.D, 3]()
        for i in range(3):
            p[i] = float(a[i])
        return p

    def vector(a):
        v = itk.Vector[itk.D, 3]()
        for i in range(3):
            v[i] = float(a[i])
        return v

    for k in range(len(sources)):
        if not geometry.AddProjection(point(sources[k]), point(detectors[k]), vector(rows[k]), vector(columns[k])):
            raise SweepError(f"RTK refused frame {k} (AddProjection returned false)")
    return geometry


def rtk_frames(sweep, scale: float = MM, layout: str = "image", geometry_only: bool = False) -> tuple[np.ndarray, ...]:
    """What RTK's ``AddProjection`` takes per frame, (n, 3) each: the source and the principal point's foot on the
    detector (world units ``scale`` per metre), the detector's row and column directions of ``layout``."""
    scale = _scale(scale)
    s, R, f, *_ = _frames(sweep, geometry_only)
    u_dir, v_dir = rtk_detector_axes(sweep, layout, geometry_only)
    return s * scale, (s + f * R[:, :, 2]) * scale, R @ u_dir, R @ v_dir


def rtk_matrices(geometry) -> np.ndarray:
    """``GetMatrix(i)`` of every projection of an RTK geometry, (n, 3, 4)."""
    itk, _ = _rtk()
    return np.array([itk.array_from_vnl_matrix(geometry.GetMatrix(i).GetVnlMatrix().as_matrix())
                     for i in range(len(geometry.GetGantryAngles()))])


def pixel_from_detector(sweep, scale: float = MM, layout: str = "image") -> np.ndarray:
    """(3, 3) map of homogeneous RTK detector physical coordinates (u, v, 1) to our pixels (c, r, 1):
    ``(c − u0) sx = u (u_dir·x) + v (v_dir·x)``, ``(r − v0) sy = u (u_dir·y) + v (v_dir·y)``."""
    scale = _scale(scale)
    _, _, _, (sx, sy), (u0, v0), _ = _frames(sweep)
    u_dir, v_dir = rtk_detector_axes(sweep, layout)
    return np.array([[u_dir[0] / (sx * scale), v_dir[0] / (sx * scale), u0],
                     [u_dir[1] / (sy * scale), v_dir[1] / (sy * scale), v0], [0.0, 0.0, 1.0]])


def rtk_projection_grid(sweep, scale: float = MM, layout: str = "image", geometry_only: bool = False):
    """``(origin (3,), spacing (3,), size (3,))`` of the RTK projection stack (frame k at z = k): its index
    (i, j) along (u, v) is one of our pixels — ``to_rtk_stack`` reorders our images accordingly."""
    scale = _scale(scale)
    _, _, _, (sx, sy), (u0, v0), (cols, rows) = _frames(sweep, geometry_only)
    origin, spacing, size = [], [], []
    for d in rtk_detector_axes(sweep, layout, geometry_only):
        along_x = abs(d[0]) > 0.5
        pitch, centre, count = (sx, u0, cols) if along_x else (sy, v0, rows)
        sign = d[0] if along_x else d[1]
        # physical = sign·(pixel − centre)·pitch; index = pixel (sign +) or count − 1 − pixel (sign −)
        first = -centre if sign > 0 else -(count - 1 - centre)
        origin.append(first * pitch * scale)
        spacing.append(pitch * scale)
        size.append(count)
    return np.array(origin + [0.0]), np.array(spacing + [1.0]), (size[0], size[1], sweep.n_views)


def to_rtk_stack(sweep, images: np.ndarray, layout: str = "image") -> np.ndarray:
    """Our images (n, rows, cols) as the RTK stack array (n, size_v, size_u) of :func:`rtk_projection_grid`."""
    u_dir, v_dir = rtk_detector_axes(sweep, layout)
    out = np.asarray(images)
    if abs(u_dir[0]) < 0.5:  # u along our rows: transpose to (n, cols, rows)
        out = out.transpose(0, 2, 1)
    if (u_dir[0] + u_dir[1]) < 0:
        out = out[:, :, ::-1]
    if (v_dir[0] + v_dir[1]) < 0:
        out = out[:, ::-1, :]
    return np.ascontiguousarray(out)


def write_rtk_xml(sweep, path, scale: float = MM, layout: str = "image") -> None:
    """Write the RTK geometry of ``sweep`` to an XML file in RTK's format (:mod:`.rtk_xml`: no itk-rtk needed)."""
    from . import rtk_xml

    rtk_xml.write(path, *rtk_frames(sweep, _scale(scale), layout))
