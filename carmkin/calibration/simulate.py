"""Measured projection matrices of a simulated device: the reference points projected by the true system,
Gaussian noise of ``noise_px`` added to each pixel coordinate, and P re-estimated from the noisy pixels by the
normalised DLT refined to the least reprojection error (the "gold standard" estimate, Hartley & Zisserman
§7.2) — what a phantom calibration of each view would hand over.
"""

from __future__ import annotations

import numpy as np

from carmkin.errors import CalibrationError
from carmkin.model.system import CArmSystem, require_system
from carmkin.validation import integer, pixel_array, point_array, real_array, real_scalar

from .reprojection import MIN_POINTS, checked_readings, model_projections, pixels, reference_points

#: A device off its nominal model by a few mm, tenths of a degree and pixels (each parameter's unit), for the
#: acceptance check, the docs and the notebook; it leaves alone the four parameters no set of views separates
#: from a joint zero offset (length_offset, gamma3, D2, D3: docs/calibration.md).
EXAMPLE_PERTURBATION = {
    "table_translation_zero_offset": 1.5, "vertical_zero_offset": -2.0, "wigwag_zero_offset": 0.2,
    "horizontal_zero_offset": 2.5, "angular_zero_offset": -0.3, "orbital_zero_offset": 0.4,
    "source_to_detector": 4.0, "principal_point_u": 3.0, "principal_point_v": -2.0, "detector_rotation": 0.3,
    "orbital_offset": 3.0, "a1": 2.0, "a2": -1.5, "gamma1": 0.2, "gamma2": -0.3, "D1": 2.0,
    "sag_cos": 1.0, "sag_sin": -2.0,
}
#: The fraction of each joint's range left out at both ends by :func:`spread_readings` (10 %).
RANGE_MARGIN = 0.1


def spread_readings(system: CArmSystem, n: int, seed: int = 0, joints=None) -> np.ndarray:
    """Joint readings (n, nq) spread over the joints: uniform in the middle 80 % of each joint's range
    (:data:`RANGE_MARGIN`), from ``numpy.random.default_rng(seed)``. ``joints``: names of the joints that move
    (default all); the others stay at the middle of their range (e.g. ``joints=("orbital",)``: an orbital sweep
    in random order)."""
    require_system(system, CalibrationError)
    n, seed = integer(n, "n", low=1, error=CalibrationError), integer(seed, "seed", low=0, error=CalibrationError)
    lower, upper = system.lower, system.upper
    u = np.random.default_rng(seed).uniform(RANGE_MARGIN, 1.0 - RANGE_MARGIN, (n, system.nq))
    if joints is not None:
        if isinstance(joints, str) or not hasattr(joints, "__iter__"):
            raise CalibrationError(f"joints must be a list of joint names, got {joints!r:.80}")
        joints = list(joints)
        if not all(isinstance(j, str) for j in joints):
            raise CalibrationError(f"joints must be joint names (text), got {joints!r:.80}")
        unknown = [j for j in joints if j not in system.joint_names]
        if unknown:
            raise CalibrationError(f"joints: unknown joint(s) {unknown}; joints: {', '.join(system.joint_names)}")
        u[:, [name not in joints for name in system.joint_names]] = 0.5
    return lower + (upper - lower) * u


def measured_projections(system: CArmSystem, q, noise_px: float = 0.1, seed: int = 0, points=None) -> np.ndarray:
    """Simulated measured P (N, 3, 4) of ``system`` (the "true" device, e.g. :func:`.quantities.adjust` of a
    preset) at joint readings ``q`` (N, nq); ``points`` (N, M, 3) m (default: the reference points of
    ``system``); noise σ = ``noise_px`` per pixel coordinate, from ``numpy.random.default_rng(seed)``."""
    Q = checked_readings(system, q)
    noise = real_scalar(noise_px, "noise_px", error=CalibrationError, low=0.0, unit="px")
    seed = integer(seed, "seed", low=0, error=CalibrationError)
    X = reference_points(system, Q) if points is None else real_array(points, "points", (len(Q), None, 3),
                                                                      error=CalibrationError, unit="m")
    observed = pixels(model_projections(system, Q), X)
    observed = observed + np.random.default_rng(seed).normal(0.0, noise, observed.shape)
    return np.array([estimate_projection(X[i], observed[i]) for i in range(len(Q))])


def estimate_projection(X: np.ndarray, x: np.ndarray) -> np.ndarray:
    """P (3, 4) from points X (M, 3) (m) and their pixels x (M, 2) (px), M ≥ 6: normalised DLT, then
    Levenberg–Marquardt on the reprojection error; scaled to ``||P[2, :3]|| = 1``. CalibrationError naming X
    or x when they are not finite, mis-shaped, fewer than 6 or of different counts."""
    from scipy.optimize import least_squares

    X = point_array(X, "X (reference points)", error=CalibrationError, min_count=MIN_POINTS)
    x = pixel_array(x, "x (their pixels)", error=CalibrationError, min_count=MIN_POINTS)
    if len(x) != len(X):
        raise CalibrationError(f"X has {len(X)} points but x has {len(x)} pixels: need one pixel per point")

    def normaliser(points):
        centre = points.mean(axis=0)
        scale = np.sqrt(points.shape[1]) / np.mean(np.linalg.norm(points - centre, axis=1))
        T = np.eye(points.shape[1] + 1)
        T[:-1, :-1] *= scale
        T[:-1, -1] = -scale * centre
        return T

    T3, T2 = normaliser(X), normaliser(x)
    Xn = (np.column_stack((X, np.ones(len(X)))) @ T3.T)
    xn = (np.column_stack((x, np.ones(len(x)))) @ T2.T)
    rows = []
    for Xh, (u, v, _) in zip(Xn, xn):
        rows.append(np.concatenate((Xh, np.zeros(4), -u * Xh)))
        rows.append(np.concatenate((np.zeros(4), Xh, -v * Xh)))
    P = np.linalg.solve(T2, np.linalg.svd(np.array(rows))[2][-1].reshape(3, 4) @ T3)
    P /= np.linalg.norm(P[2, :3])

    def reprojection(p):
        return (pixels(p.reshape(1, 3, 4), X[None])[0] - x).ravel()

    P = least_squares(reprojection, P.ravel(), method="lm", xtol=1e-15, ftol=1e-15).x.reshape(3, 4)
    return P / np.linalg.norm(P[2, :3])
