"""What a view shows of the anatomy, under the C-arm's perspective projection, for many views at once.

A view is a source pose ``T`` (4, 4, table frame; z = the beam, source → detector) with the pinhole intrinsics
``K`` of the system (:func:`carmkin.imaging.intrinsics`: the detector's pixel size and SID). Every function takes
``poses`` (C, 4, 4) and answers (C,) arrays, vectorised over the views (no Python loop over views or points).
Coordinates: a point ``X`` (table frame, m) has camera coordinates ``(x, y, z) = Rᵀ (X − t)``, normalised image
coordinates ``(x/z, y/z)`` (detector metres over the SID) and pixels ``K (x/z, y/z, 1)`` (pixel centres at
integers).

**Foreshortening** of a centreline (Chen & Carroll 2000, IEEE TMI 19(4) "3-D reconstruction of a coronary
artery tree to optimize angiographic visualization"; Green et al. 2005, Catheter Cardiovasc Interv 64:451,
"optimal views" of 156 coronary segments; the percent foreshortening of a segment is its 3D length minus its
projected length over magnification, over its 3D length):

    F = 1 − L_projected / (M · L_3D),   M = SID / distance,

``L_projected`` the polyline's arc length on the detector, ``L_3D`` its 3D arc length and ``M`` the
magnification at the target's depth ``distance`` (source–target along the beam). In normalised coordinates
``F = 1 − distance · L_normalised / L_3D``. A segment in the plane through the target across the beam has
F = 0 exactly; one at angle θ to that plane has F → 1 − cos θ as the source moves away (parallel projection).
F may be slightly negative (parts nearer the source than the target are magnified more). The worst local
foreshortening is the same ratio for each polyline segment, its maximum.

**Overlap** (Green et al. 2005: percent of the segment overlapped by other vessels): the projected centreline
is sampled on every segment of the polyline at :data:`SAMPLE_SPACING_PX` pixels or less (the same subdivision
in every view); the pixels holding a sample are the centreline's pixels; a pixel is covered when its centre lies
inside the projected tube of another vessel: the union over that vessel's polyline segments of the 2D capsule
about the projected segment with radius ``r / z_mid`` (normalised; ``r`` the segment's mean radius, ``z_mid``
the mean depth of its ends). Overlap = covered pixels / centreline pixels (pixels on the unbounded grid of the
detector's pixel size).
"""

from __future__ import annotations

import numpy as np

from carmkin.errors import ViewError

#: Largest spacing (px) of the samples of the projected centreline (overlap).
SAMPLE_SPACING_PX = 0.5
#: Tube radius (m) of the other vessels when no radii are given (a mid-size coronary branch, 3 mm across).
DEFAULT_RADIUS = 1.5e-3
#: Smallest depth (m) in front of the source a projected point may have.
MIN_DEPTH = 1e-3
#: Sample × view elements processed per chunk of the overlap (memory bound, ~100 MB).
CHUNK_ELEMENTS = 1 << 19
#: Longest projected piece (px) the other vessels' segments are cut into for the overlap's grid join.
PIECE_PX = 8.0


def xa_poses(primary_deg, secondary_deg, target, distance: float, R_patient=np.eye(3)) -> np.ndarray:
    """Source poses (C, 4, 4, table frame) of XA angles (deg, arrays (C,)) at rotation 0, the source
    ``distance`` (m) from ``target`` (3,) m along the beam, for a patient whose LPS axes are the columns of
    ``R_patient``: :func:`carmkin.interop.dicom.pose_from_xa_angles` for many views."""
    from carmkin.interop.dicom import SOURCE_IN_POSITIONER

    a1, a2 = np.radians(np.asarray(primary_deg, dtype=float)), np.radians(np.asarray(secondary_deg, dtype=float))
    c1, s1, c2, s2 = np.cos(a1), np.sin(a1), np.cos(a2), np.sin(a2)
    zero, one = np.zeros_like(a1), np.ones_like(a1)
    R1 = np.stack([np.stack([c1, s1, zero], -1), np.stack([-s1, c1, zero], -1), np.stack([zero, zero, one], -1)], -2)
    R2 = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, c2, -s2], -1), np.stack([zero, s2, c2], -1)], -2)
    M = R2 @ R1
    T = np.zeros(a1.shape + (4, 4))
    T[..., :3, :3] = np.asarray(R_patient) @ np.swapaxes(M, -1, -2) @ SOURCE_IN_POSITIONER
    T[..., :3, 3] = np.asarray(target, dtype=float) - distance * T[..., :3, 2]
    T[..., 3, 3] = 1.0
    return T


def camera_points(points, poses) -> np.ndarray:
    """Camera coordinates (C, N, 3) of ``points`` (N, 3) m in the views ``poses`` (C, 4, 4); refuses a point
    less than :data:`MIN_DEPTH` in front of a source."""
    P = np.asarray(points, dtype=float)
    T = np.asarray(poses, dtype=float)
    R = T[:, :3, :3]
    cam = np.matmul(P, R) - np.matmul(T[:, None, :3, 3], R)
    if np.any(cam[..., 2] < MIN_DEPTH):
        raise ViewError(f"the anatomy reaches within {MIN_DEPTH * 1e3:g} mm of the source (or behind it) in some "
                        "view: it must lie between source and detector")
    return cam


def _normalised(cam):
    return cam[..., :2] / cam[..., 2:3]


def foreshortening(points, poses, distance) -> tuple[np.ndarray, np.ndarray]:
    """``(F, worst)`` (C,): the foreshortening of the polyline ``points`` (N, 3) m (module docstring) in each
    view and its worst segment's, ``distance`` (m, scalar or (C,)) the source–target distance of each view."""
    xy = _normalised(camera_points(points, poses))
    projected = np.linalg.norm(np.diff(xy, axis=1), axis=2)                      # (C, N-1), normalised
    length = np.linalg.norm(np.diff(np.asarray(points, dtype=float), axis=0), axis=1)  # (N-1,) m
    d = np.reshape(np.asarray(distance, dtype=float), (-1, 1))
    total = 1.0 - d[:, 0] * projected.sum(axis=1) / length.sum()
    worst = np.max(1.0 - d * projected / length, axis=1)
    return total, worst


def plane_angle(normal, directions) -> np.ndarray:
    """Angle (rad) between each beam ``directions`` (C, 3) unit and the plane of unit ``normal`` (3,): 0 when
    the beam lies in the plane (the plane seen edge-on)."""
    return np.arcsin(np.clip(np.abs(np.asarray(directions) @ np.asarray(normal)), 0.0, 1.0))


def separation(points, poses, distance) -> np.ndarray:
    """Smallest projected distance (C,) between any two of ``points`` (K, 3) m (e.g. cusp nadirs) in each view,
    in m at the target's depth (detector distance over the magnification)."""
    xy = _normalised(camera_points(points, poses))
    gaps = np.linalg.norm(xy[:, :, None] - xy[:, None], axis=-1)
    k = len(xy[0])
    gaps[:, np.arange(k), np.arange(k)] = np.inf
    return gaps.reshape(len(gaps), -1).min(axis=1) * np.asarray(distance, dtype=float)


def _pixels(xy, K):
    return np.stack((K[0, 0] * xy[..., 0] + K[0, 1] * xy[..., 1] + K[0, 2], K[1, 1] * xy[..., 1] + K[1, 2]), -1)


def _tube_pieces(others, radii, poses, K):
    """The others' polyline segments cut into equal 3D pieces (each no longer than :data:`PIECE_PX` projected
    in any view): ends A, B (S, 3) m and their parent segment's ends' mean depth is used for the radius, so
    the union of the pieces' capsules is the parent's capsule. Returns A, B, parent ends Pa, Pb, radius (S,)."""
    A, B, Pa, Pb, R = [], [], [], [], []
    for points, r in zip(others, radii):
        points = np.asarray(points, dtype=float)
        r = np.broadcast_to(np.asarray(r, dtype=float), (len(points),))
        n = subdivisions(points, poses, K, PIECE_PX)
        k = np.repeat(np.arange(len(n)), n)
        f = np.concatenate([np.arange(m) / m for m in n])
        g = np.concatenate([np.arange(1, m + 1) / m for m in n])
        a, b = points[:-1][k], points[1:][k]
        A.append(a + f[:, None] * (b - a)), B.append(a + g[:, None] * (b - a))
        Pa.append(a), Pb.append(b), R.append((0.5 * (r[:-1] + r[1:]))[k])
    if not A:
        return (np.zeros((0, 3)),) * 4 + (np.zeros(0),)
    return np.vstack(A), np.vstack(B), np.vstack(Pa), np.vstack(Pb), np.concatenate(R)


def subdivisions(points, poses, K, spacing: float = SAMPLE_SPACING_PX) -> np.ndarray:
    """Samples per polyline segment (N-1,) so that no projected sample step exceeds ``spacing`` px in any view."""
    px = _pixels(_normalised(camera_points(points, poses)), np.asarray(K, dtype=float))
    longest = np.linalg.norm(np.diff(px, axis=1), axis=2).max(axis=0)
    return np.maximum(1, np.ceil(longest / spacing)).astype(int)


def overlap(points, others, poses, K, radii=DEFAULT_RADIUS, counts=None) -> np.ndarray:
    """Overlap (C,) of the centreline ``points`` (N, 3) m by the tubes about ``others`` (a sequence of (M, 3)
    polylines, m; ``radii`` one radius (m) for all, or one per polyline: a scalar or (M,) per point) in each
    view (module docstring). ``counts`` (N-1,): the subdivision of each segment (default
    :func:`subdivisions` over these views). Vectorised: the centreline's pixels and the tubes' pieces meet
    through a coarse grid (a sort and a join), so only pixels near a piece are tested."""
    K = np.asarray(K, dtype=float)
    points = np.asarray(points, dtype=float)
    poses = np.asarray(poses, dtype=float)
    others = list(others)
    radii = [radii] * len(others) if np.ndim(radii) == 0 else list(radii)
    if counts is None:
        counts = subdivisions(points, poses, K)
    seg = np.repeat(np.arange(len(counts)), counts)
    t = np.concatenate([np.arange(n) / n for n in counts])
    seg, t = np.append(seg, len(counts) - 1), np.append(t, 1.0)  # the last point
    tubes = _tube_pieces(others, radii, poses, K)
    chunk = max(1, CHUNK_ELEMENTS // len(seg))
    out = np.empty(len(poses))
    for lo in range(0, len(poses), chunk):
        out[lo:lo + chunk] = _overlap_chunk(points, poses[lo:lo + chunk], K, seg, t, tubes)
    return out


def _overlap_chunk(points, poses, K, seg, t, tubes):
    C = len(poses)
    px = _pixels(_normalised(camera_points(points, poses)), K)                   # (C, N, 2)
    samples = px[:, seg] + t[:, None] * (px[:, seg + 1] - px[:, seg])           # (C, Ns, 2)
    iu = np.floor(samples[..., 0] + 0.5).astype(np.int64)
    iv = np.floor(samples[..., 1] + 0.5).astype(np.int64)
    keep = np.ones(iu.shape, dtype=bool)                                        # drop repeats in a row
    keep[:, 1:] = (iu[:, 1:] != iu[:, :-1]) | (iv[:, 1:] != iv[:, :-1])
    cell, iu, iv = np.nonzero(keep)[0], iu[keep], iv[keep]
    u0, v0 = iu.min(), iv.min()
    width, height = int(iu.max() - u0) + 1, int(iv.max() - v0) + 1
    key = np.sort((cell * width + (iu - u0)) * height + (iv - v0))               # each cell's pixels once
    key = key[np.r_[True, key[1:] != key[:-1]]]
    cell, rest = np.divmod(key, width * height)
    iu, iv = rest // height + u0, rest % height + v0
    total = np.bincount(cell, minlength=C)
    A, B, Pa, Pb, R = tubes
    if not len(A):
        return np.zeros(C)
    y = (iv - K[1, 2]) / K[1, 1]
    centres = np.stack(((iu - K[0, 2] - K[0, 1] * y) / K[0, 0], y), -1)        # pixel centres, normalised
    a, b = _normalised(camera_points(A, poses)), _normalised(camera_points(B, poses))  # (C, S, 2)
    r = R / (0.5 * (camera_points(Pa, poses)[..., 2] + camera_points(Pb, poses)[..., 2]))  # (C, S)
    lo, hi = np.minimum(a, b) - r[..., None], np.maximum(a, b) + r[..., None]
    size = max(float(np.max(hi - lo)), 1e-12)                                   # grid step: a piece spans <= 2
    g_lo, g_hi = np.floor(lo / size).astype(np.int64), np.floor(hi / size).astype(np.int64)
    g_pix = np.floor(centres / size).astype(np.int64)
    gmin = np.minimum(g_lo.reshape(-1, 2).min(axis=0), g_pix.min(axis=0))
    gspan = np.maximum(g_hi.reshape(-1, 2).max(axis=0), g_pix.max(axis=0)) - gmin + 1
    ci, si = np.meshgrid(np.arange(C), np.arange(A.shape[0]), indexing="ij")
    keys, owners = [], []
    for dx in (0, 1):
        for dy in (0, 1):
            gx, gy = g_lo[..., 0] + dx, g_lo[..., 1] + dy
            ok = (gx <= g_hi[..., 0]) & (gy <= g_hi[..., 1])
            keys.append(((ci[ok] * gspan[0] + gx[ok] - gmin[0]) * gspan[1] + gy[ok] - gmin[1]))
            owners.append(np.column_stack((ci[ok], si[ok])))
    keys, owners = np.concatenate(keys), np.vstack(owners)
    order = np.argsort(keys, kind="stable")
    keys, owners = keys[order], owners[order]
    pkey = (cell * gspan[0] + g_pix[:, 0] - gmin[0]) * gspan[1] + g_pix[:, 1] - gmin[1]
    first, last = np.searchsorted(keys, pkey, "left"), np.searchsorted(keys, pkey, "right")
    n = last - first
    pix = np.repeat(np.arange(len(pkey)), n)
    piece = owners[np.repeat(first - np.cumsum(n) + n, n) + np.arange(n.sum())]
    c, s = piece[:, 0], piece[:, 1]
    pa, ab = a[c, s], b[c, s] - a[c, s]
    d = centres[pix] - pa
    ab2 = np.sum(ab * ab, axis=-1)
    w = np.clip(np.sum(d * ab, axis=-1) / np.where(ab2 > 0, ab2, 1.0), 0.0, 1.0)
    gap = d - w[:, None] * ab
    covered = np.zeros(len(pkey), dtype=bool)
    covered[pix[np.sum(gap * gap, axis=-1) <= r[c, s] ** 2]] = True
    return np.bincount(cell[covered], minlength=C) / total


