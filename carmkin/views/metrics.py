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
in every view; at 1 px consecutive samples round to the same or 8-adjacent pixels, so the pixels form an
8-connected digital curve, as a line rasteriser draws it); the pixels holding a sample are the centreline's pixels; a pixel is covered when its centre lies
inside the projected tube of another vessel: the union over that vessel's polyline segments of the 2D capsule
about the projected segment with radius ``r / z_mid`` (normalised; ``r`` the segment's mean radius, ``z_mid``
the mean depth of its ends). Overlap = covered pixels / centreline pixels (pixels on the unbounded grid of the
detector's pixel size).
"""

from __future__ import annotations

import numpy as np

from carmkin.errors import ViewError

#: Largest spacing (px) of the samples of the projected centreline (overlap).
SAMPLE_SPACING_PX = 1.0
#: Tube radius (m) of the other vessels when no radii are given (a mid-size coronary branch, 3 mm across).
DEFAULT_RADIUS = 1.5e-3
#: Smallest depth (m) in front of the source a projected point may have.
MIN_DEPTH = 1e-3
#: Sample × view elements processed per chunk of the overlap (memory bound, ~100 MB).
CHUNK_ELEMENTS = 1 << 15
#: Longest projected piece (px) the other vessels' segments are cut into for the overlap's grid join.
PIECE_PX = 16.0


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
    in any view; the union of the pieces' capsules is the segment's, as they keep its radius): ``vertices``
    (V, 3) m, and per piece the indices of its ends ``ia``, ``ib`` and of its segment's ends ``pa``, ``pb``
    into them, and the segment's mean radius (m)."""
    vertices, ia, ib, pa, pb, R, base = [], [], [], [], [], [], 0
    for points, r in zip(others, radii):
        points = np.asarray(points, dtype=float)
        r = np.broadcast_to(np.asarray(r, dtype=float), (len(points),))
        n = subdivisions(points, poses, K, PIECE_PX)
        k = np.repeat(np.arange(len(n)), n)
        f = np.concatenate([np.arange(m) / m for m in n])
        inner = points[:-1][k] + f[:, None] * (points[1:] - points[:-1])[k]       # each piece's first end
        vertices += [points, inner]
        first = base + len(points) + np.arange(len(k))                           # index of each piece's start
        ia.append(first)
        ib.append(np.where(np.r_[k[1:] == k[:-1], False], first + 1, base + k + 1))
        pa.append(base + k), pb.append(base + k + 1), R.append((0.5 * (r[:-1] + r[1:]))[k])
        base += len(points) + len(k)
    if not vertices:
        return np.zeros((0, 3)), *(np.zeros(0, dtype=int),) * 4, np.zeros(0)
    return (np.vstack(vertices), *(np.concatenate(v) for v in (ia, ib, pa, pb)), np.concatenate(R))


def subdivisions(points, poses, K, spacing: float = SAMPLE_SPACING_PX, per_view: bool = False) -> np.ndarray:
    """Samples per polyline segment (N-1,) so that no projected sample step exceeds ``spacing`` px in any view
    (at 1 px, consecutive samples fall in the same or 8-adjacent pixels: an 8-connected digital curve);
    ``per_view``: each view's own (C, N-1), which depends on that view alone."""
    px = _pixels(_normalised(camera_points(points, poses)), np.asarray(K, dtype=float))
    longest = np.linalg.norm(np.diff(px, axis=1), axis=2)
    return np.maximum(1, np.ceil((longest if per_view else longest.max(axis=0)) / spacing)).astype(int)


def overlap(points, others, poses, K, radii=DEFAULT_RADIUS, counts=None) -> np.ndarray:
    """Overlap (C,) of the centreline ``points`` (N, 3) m by the tubes about ``others`` (a sequence of (M, 3)
    polylines, m; ``radii`` one radius (m) for all, or one per polyline: a scalar or (M,) per point) in each
    view (module docstring). ``counts``: the subdivision of each segment, (N-1,) for every view or (C, N-1)
    (default: each view's own, :func:`subdivisions` with ``per_view``, so that a view's overlap does not depend
    on the other views of the call — a cell alone and in a full map agree exactly, issue 41). Vectorised: the
    centreline's pixels and the tubes' pieces meet through a coarse grid (a sort and a join), so only pixels
    near a piece are tested."""
    K = np.asarray(K, dtype=float)
    points = np.asarray(points, dtype=float)
    poses = np.asarray(poses, dtype=float)
    others = list(others)
    if not isinstance(radii, (list, tuple)):  # one radius for all, or (M,) per point of a single vessel
        radii = [radii] * len(others) if np.ndim(radii) == 0 else list(radii)
    # a list: one entry per vessel, each a radius or (M,) per point; lengths may differ (issue 41)
    if counts is None:
        counts = subdivisions(points, poses, K, per_view=True)
    counts = np.broadcast_to(np.asarray(counts, dtype=np.int64), (len(poses), len(points) - 1))
    most = counts.max(axis=0)                                                   # samples k = 0 … most − 1
    seg = np.repeat(np.arange(len(most)), most)
    k = np.concatenate([np.arange(n) for n in most])
    tubes = _tube_pieces(others, radii, poses, K)
    chunk = max(1, CHUNK_ELEMENTS // (len(seg) + 1))
    starts = range(0, len(poses), chunk)

    def work(lo):
        n = counts[lo:lo + chunk, seg]                                           # each view's own subdivision
        t = np.where(k < n, k / n, 1.0)   # past a view's own samples: the segment's end (a repeat, dropped)
        t = np.concatenate((t, np.ones((len(t), 1))), axis=1)                    # the last point
        return _overlap_chunk(points, poses[lo:lo + chunk], K, np.append(seg, len(most) - 1), t, tubes)

    if len(starts) == 1:
        return work(0)
    from concurrent.futures import ThreadPoolExecutor

    from .maps import default_workers

    with ThreadPoolExecutor(default_workers()) as pool:  # numpy releases the GIL in the heavy steps
        return np.concatenate(list(pool.map(work, starts)))


def _overlap_chunk(points, poses, K, seg, t, tubes):
    C = len(poses)
    xy = _normalised(camera_points(points, poses))
    pu = K[0, 0] * xy[..., 0] + K[0, 1] * xy[..., 1] + K[0, 2]                 # (C, N) pixels
    pv = K[1, 1] * xy[..., 1] + K[1, 2]
    iu = np.floor(pu[:, seg] + t * np.diff(pu, axis=1, append=pu[:, -1:])[:, seg] + 0.5).astype(np.int64)
    iv = np.floor(pv[:, seg] + t * np.diff(pv, axis=1, append=pv[:, -1:])[:, seg] + 0.5).astype(np.int64)
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
    vertices, ia, ib, pa, pb, R = tubes
    if not len(ia):
        return np.zeros(C)
    y = (iv - K[1, 2]) / K[1, 1]                                                # pixel centres, normalised
    x = (iu - K[0, 2] - K[0, 1] * y) / K[0, 0]
    cam = camera_points(vertices, poses)
    xy, depth = _normalised(cam), cam[..., 2]
    a, b = xy[:, ia], xy[:, ib]                                                 # (C, S, 2)
    r = R / (0.5 * (depth[:, pa] + depth[:, pb]))                               # (C, S) normalised radius
    lo, hi = np.minimum(a, b) - r[..., None], np.maximum(a, b) + r[..., None]
    low = np.stack((_per_cell(x, cell, C, np.minimum), _per_cell(y, cell, C, np.minimum)), -1)
    high = np.stack((_per_cell(x, cell, C, np.maximum), _per_cell(y, cell, C, np.maximum)), -1)
    ci, si = np.nonzero(np.all((lo <= high[:, None]) & (hi >= low[:, None]), axis=-1))  # pieces near the vessel
    if not len(ci):
        return np.zeros(C)
    lo, hi = lo[ci, si], hi[ci, si]
    ax, ay = a[ci, si, 0], a[ci, si, 1]
    ux, uy = b[ci, si, 0] - ax, b[ci, si, 1] - ay
    length2 = ux * ux + uy * uy
    inverse = np.divide(1.0, length2, out=np.zeros_like(length2), where=length2 > 0)
    r2 = r[ci, si] ** 2
    size = max(float(np.max(hi - lo)), 1e-12)                                   # grid step: a piece spans <= 2
    g_lo, g_hi = np.floor(lo / size).astype(np.int64), np.floor(hi / size).astype(np.int64)
    gx, gy = np.floor(x / size).astype(np.int64), np.floor(y / size).astype(np.int64)
    gmin = np.minimum(g_lo.min(axis=0), (gx.min(), gy.min()))
    span = np.maximum(g_hi.max(axis=0), (gx.max(), gy.max())) - gmin + 1
    keys, owners = [], []
    for dx in (0, 1):
        for dy in (0, 1):
            ok = np.nonzero((g_lo[:, 0] + dx <= g_hi[:, 0]) & (g_lo[:, 1] + dy <= g_hi[:, 1]))[0]
            keys.append((ci[ok] * span[0] + g_lo[ok, 0] + dx - gmin[0]) * span[1] + g_lo[ok, 1] + dy - gmin[1])
            owners.append(ok)
    keys, owners = np.concatenate(keys), np.concatenate(owners)
    order = np.argsort(keys)
    keys, owners = keys[order], owners[order]
    pkey = (cell * span[0] + gx - gmin[0]) * span[1] + gy - gmin[1]
    first = np.searchsorted(keys, pkey, "left")
    n = np.searchsorted(keys, pkey, "right") - first
    pix = np.repeat(np.arange(len(pkey)), n)
    piece = owners[np.repeat(first - np.cumsum(n) + n, n) + np.arange(n.sum())]
    dx, dy = x[pix] - ax[piece], y[pix] - ay[piece]
    w = np.clip((dx * ux[piece] + dy * uy[piece]) * inverse[piece], 0.0, 1.0)
    dx -= w * ux[piece]
    dy -= w * uy[piece]
    covered = np.zeros(len(pkey), dtype=bool)
    covered[pix[dx * dx + dy * dy <= r2[piece]]] = True
    return np.bincount(cell[covered], minlength=C) / total


def _per_cell(values, cell, C, ufunc):
    """``ufunc`` (np.minimum or np.maximum) of ``values`` over each cell's entries (cells sorted, each present)."""
    return ufunc.reduceat(values, np.searchsorted(cell, np.arange(C)))
