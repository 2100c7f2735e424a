"""Pose priors of synthetic X-ray datasets, each sample feasible by construction (joints in range, clearance
≥ the margin to table, floor and patient): proposals are drawn, the views' search (or the exact clearance)
keeps the feasible ones, rejections are counted by reason.

* ``standard-views``: the named standard views (:mod:`carmkin.views.standard`), each proposal a view drawn
  uniformly, its primary and secondary angles perturbed by a Gaussian of SD :data:`CLINICAL_SD_DEG` — the X-ray
  Genius user guide ("How to Use X-ray Genius", https://app.xray-genius.com/guide/, §1 Rotation: "Randomize with
  a standard deviation of 2.5° to simulate a reasonable level of clinical variance"); the roll about the beam
  is the planner's (free) or, with ``roll_sd_deg``, Gaussian about the roll the C-arm takes for the view when
  it is free (a mobile C-arm rolls the image only through its wigwag, so rotation 0 is no nominal roll).
* ``reachable-sphere``: directions uniform over the part of the view sphere the system reaches: a
  :func:`carmkin.views.reach_map` of ``cell_deg`` cells at the target, a reachable cell drawn with probability
  ∝ its area on the sphere, the direction uniform on the sphere inside it, the target jittered uniformly in
  a cube of half-side ``jitter_mm``; every proposal searched again (partly reachable cells reject).
* ``sweep``: cone-beam sweeps (:func:`carmkin.sweeps.plan_sweep`) of ``n_views`` frames over ``arc_deg``
  about the orbital joint around the target jittered in the same cube; a sweep that does not fit is rejected
  whole.
* ``joint-uniform``: q uniform in the joint ranges, kept where the exact clearance keeps the margin.

Targets in the table frame (m); the default target is 0.15 m anterior of the patient model's reference point
(mid-sagittal, back plane, nipple level: inside the chest), or the table origin without a model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import DatasetError

from .samples import Rejections, patient_frame

#: SD (deg) of the clinical variance about a standard view (the X-ray Genius user guide, §1 Rotation and §2 Tilt).
CLINICAL_SD_DEG = 2.5
#: Depth (m) of the default target in front of the patient's reference point (LPS −y: anterior; the
#: table origin for a patient lying on the preset tables, where the views and sweeps tests aim).
TARGET_DEPTH = 0.15
#: Proposals per round: at least this many, at most :data:`MAX_ROUND`.
MIN_ROUND, MAX_ROUND = 32, 20_000
#: A prior proposes at most this many times the samples asked for before it says it cannot be met.
MAX_PROPOSAL_FACTOR = 50
#: A group (standard view) with this many proposals and none accepted is reported as unreachable.
UNREACHABLE_AFTER = 20

PRIORS = ("standard-views", "reachable-sphere", "sweep", "joint-uniform")


def default_target(patient) -> np.ndarray:
    """The default target (3,) m, table frame (see the module docstring)."""
    if patient is not None and callable(getattr(patient, "pose", None)):
        return (patient.pose() @ np.array([0.0, -TARGET_DEPTH, 0.0, 1.0]))[:3]
    return np.zeros(3)


def _target(value, patient) -> np.ndarray:
    from carmkin.validation import real_array

    if value is None:
        return default_target(patient)
    return real_array(value, "target_m", (3,), error=DatasetError, unit="m")


def _number(value, name, low, high, unit) -> float:
    from carmkin.validation import real_scalar

    return real_scalar(value, name, error=DatasetError, low=low, high=high, unit=unit)


def _integer(value, name, low, high) -> int:
    from carmkin.validation import integer

    return integer(value, name, low=low, high=high, error=DatasetError)


# --- the views' search, many cells at once ------------------------------------------------------------------
def search(system, patient, targets, directions, margin: float, x_axes=None):
    """The views' search (:func:`carmkin.views.plan_view`'s, no ``q_current``) of many beams: targets and
    directions (N, 3) in the table frame, ``x_axes`` (N, 3) fixed rolls (NaN rows: free) -> its outcome
    (``reachable``, ``q``, ``binding`` per cell)."""
    from carmkin.views import search as view_search
    from carmkin.views.plan import reference, world_for

    ctx = view_search.make_context(system, world_for(system, patient), margin, reference(system, None))
    ranges = np.tile([0.0, system.carm.source_to_detector], (len(targets), 1))
    return view_search.solve_cells(ctx, np.asarray(targets, float), np.asarray(directions, float), ranges, x_axes)


def directions(patient, primary_deg, secondary_deg) -> np.ndarray:
    """Beam directions (N, 3, table frame) of XA angles (deg) for the patient."""
    from carmkin.views.plan import beam_directions

    return beam_directions(patient_frame(patient)[:3, :3], np.radians(primary_deg), np.radians(secondary_deg))


def wrap_deg(angle):
    """Angles (deg) wrapped into [−180, 180)."""
    return (np.asarray(angle, dtype=float) + 180.0) % 360.0 - 180.0


# --- the rejection loop ------------------------------------------------------------------------------------
@dataclass
class _Tally:
    proposed: int = 0
    accepted: int = 0

    def __post_init__(self):
        self.reasons: dict = {}
        self.groups: dict = {}

    def add(self, keep, binding, groups) -> None:
        self.proposed += len(keep)
        self.accepted += int(np.sum(keep))
        for b in np.asarray(binding, dtype=object)[~keep].tolist():
            key = str(b) or "unreachable"
            self.reasons[key] = self.reasons.get(key, 0) + 1
        for g, k in zip(np.asarray(groups, dtype=object).tolist(), np.asarray(keep).tolist()):
            p, a = self.groups.get(g, (0, 0))
            self.groups[g] = (p + 1, a + int(k))

    def rejections(self, notes=(), statistics=None) -> Rejections:
        groups = {g: v for g, v in self.groups.items() if g != ""}
        dead = [g for g, (p, a) in groups.items() if p >= UNREACHABLE_AFTER and a == 0]
        if dead:
            notes = tuple(notes) + (f"no feasible configuration for {', '.join(dead)} in {UNREACHABLE_AFTER}+ "
                                    "proposals each: the prior cannot be met for them",)
        return Rejections(self.proposed, self.accepted, dict(self.reasons), groups, tuple(notes), statistics or {})


def _rounds(n: int, propose, prior: str):
    """Run ``propose(rng_count) -> (keep, binding, groups, payload...)`` in rounds until ``n`` are kept;
    returns the kept payload rows (first n, in proposal order) and the tally."""
    tally, kept = _Tally(), []
    while tally.accepted < n:
        if tally.proposed >= MAX_PROPOSAL_FACTOR * n:
            report = tally.rejections()
            raise DatasetError(f"prior {prior!r} cannot be met: {tally.accepted} of {n} samples feasible after "
                               f"{tally.proposed} proposals (rejected: {report.reasons}; {' '.join(report.notes)})")
        rate = max(tally.accepted / tally.proposed, 0.02) if tally.proposed else 1.0
        count = int(min(MAX_ROUND, max(MIN_ROUND, math.ceil(1.2 * (n - tally.accepted) / rate))))
        keep, binding, groups, *payload = propose(count)
        tally.add(keep, binding, groups)
        kept.append([np.asarray(p)[keep] for p in payload])
    columns = [np.concatenate(parts)[:n] for parts in zip(*kept)]
    return columns, tally


# --- the priors --------------------------------------------------------------------------------------------
def _standard_views_parameters(patient, views=None, sd_deg=CLINICAL_SD_DEG, roll_sd_deg=None, target_m=None):
    """(view names, sd, roll_sd, target) of the standard-views prior, checked."""
    from carmkin.views.standard import STANDARD_VIEWS

    if views is not None and (isinstance(views, str) or not isinstance(views, (list, tuple))
                              or not all(isinstance(v, str) for v in views)):
        raise DatasetError(f"views must be a list of standard view names ({', '.join(STANDARD_VIEWS)}), got {views!r:.80}")
    names = list(STANDARD_VIEWS) if views is None else [v.lower() for v in views]
    unknown = [v for v in names if v not in STANDARD_VIEWS]
    if unknown or not names:
        raise DatasetError(f"views must name standard views ({', '.join(STANDARD_VIEWS)}), got {views!r}"
                           + (f": unknown {', '.join(map(repr, unknown))}" if unknown else ""))
    sd = _number(sd_deg, "sd_deg", 0.0, 45.0, "deg")
    roll_sd = None if roll_sd_deg is None else _number(roll_sd_deg, "roll_sd_deg", 0.0, 180.0, "deg")
    return names, sd, roll_sd, _target(target_m, patient)


def standard_views(system, patient, rng, n, margin, *, views=None, sd_deg=CLINICAL_SD_DEG, roll_sd_deg=None,
                   target_m=None):
    from carmkin.views.standard import STANDARD_VIEWS

    names, sd, roll_sd, target = _standard_views_parameters(patient, views, sd_deg, roll_sd_deg, target_m)
    base = np.array([[STANDARD_VIEWS[v].primary_deg, STANDARD_VIEWS[v].secondary_deg] for v in names])
    seen = []

    def propose(count):
        k = rng.integers(len(names), size=count)
        angles = base[k] + rng.normal(0.0, sd, size=(count, 2))
        angles[:, 0] = wrap_deg(angles[:, 0])
        beams = directions(patient, *angles.T)
        out = search(system, patient, np.tile(target, (count, 1)), beams, margin)
        if roll_sd is not None:
            out = _rolled(system, patient, target, beams, out, rng.normal(0.0, roll_sd, size=count), margin)
        beyond = np.abs(angles[:, 1]) > 90.0  # no XA secondary angle: rejected, never folded back
        out.reachable[beyond], out.binding[beyond] = False, "secondary beyond ±90°"
        labels = np.array(names, dtype=object)[k]
        offsets = angles - base[k]
        offsets[:, 0] = wrap_deg(offsets[:, 0])
        seen.append((k, offsets, out.reachable))
        return out.reachable, out.binding, labels, out.q, labels, angles

    (Q, labels, nominal), tally = _rounds(n, propose, "standard-views")
    k, offsets, keep = (np.concatenate(parts) for parts in zip(*seen))
    statistics = {name: cut_statistics(offsets[k == i], keep[k == i]) for i, name in enumerate(names)}
    params = {"views": names, "sd_deg": sd, "roll_sd_deg": roll_sd, "target_m": target.tolist(),
              "sd_source": "X-ray Genius user guide (How to Use X-ray Genius, section 1 Rotation): SD 2.5 deg, "
                           "a reasonable level of clinical variance"}
    return Q, labels, nominal, tally.rejections(statistics=statistics), params


def _rolled(system, patient, target, beams, free, rolls_deg, margin):
    """The search again with the roll fixed at ``rolls_deg`` (N,) from the roll of the free plan (its source x
    axis turned towards y about the beam: minus DICOM's detector rotation), for the cells the free search
    reached; the others stay as they were."""
    out = free
    ok = np.flatnonzero(free.reachable)
    if len(ok):
        T = system.fk(free.q[ok])
        r = np.radians(rolls_deg[ok])[:, None]
        x_axes = np.cos(r) * T[:, :3, 0] + np.sin(r) * T[:, :3, 1]
        fixed = search(system, patient, np.tile(target, (len(ok), 1)), beams[ok], margin, x_axes)
        out.reachable[ok], out.q[ok], out.binding[ok] = fixed.reachable, fixed.q, fixed.binding
    return out


def cut_statistics(offsets, keep) -> dict:
    """How the feasibility cut changes a view's angles: mean and SD (deg) of the (primary, secondary) offsets
    from the view, of every proposal and of the accepted ones (NaN when none)."""
    def stats(x):
        if not len(x):
            return [math.nan] * 4
        return [float(x[:, 0].mean()), float(x[:, 0].std()), float(x[:, 1].mean()), float(x[:, 1].std())]

    return {"columns": ["primary mean", "primary SD", "secondary mean", "secondary SD"], "proposed": stats(offsets),
            "accepted": stats(offsets[keep])}


#: Reach maps of this process, by (system, patient, target, grid, margin): every shard of a dataset asks for the same.
_REACH_MAPS: dict = {}


def _reach_map(system, patient, target, primary_deg, secondary_deg, margin):
    """:func:`carmkin.views.reach_map` of the grid (one process, in order: the same map for any shard), kept
    for the next call with the same arguments when the patient is hashable."""
    from carmkin.views import reach_map

    try:
        key = (system, patient, target.tobytes(), primary_deg.tobytes(), secondary_deg.tobytes(), margin)
        hash(key)
    except TypeError:  # a list of obstacles: no cache
        key = None
    if key is not None and key in _REACH_MAPS:
        return _REACH_MAPS[key]
    cells = reach_map(system, target, primary_deg, secondary_deg, patient, margin=margin, workers=1)
    if key is not None:
        _REACH_MAPS.clear()
        _REACH_MAPS[key] = cells
    return cells


def _reachable_sphere_parameters(patient, cell_deg=5.0, jitter_mm=20.0, target_m=None):
    """(cell deg, jitter m, target) of the reachable-sphere prior, checked."""
    cell = _number(cell_deg, "cell_deg", 0.5, 45.0, "deg")
    if abs(180.0 / cell - round(180.0 / cell)) > 1e-9:
        raise DatasetError(f"cell_deg must divide 180 deg, got {cell:g}")
    return cell, _number(jitter_mm, "jitter_mm", 0.0, 500.0, "mm") / 1e3, _target(target_m, patient)


def reachable_sphere(system, patient, rng, n, margin, *, cell_deg=5.0, jitter_mm=20.0, target_m=None):
    cell, jitter, target = _reachable_sphere_parameters(patient, cell_deg, jitter_mm, target_m)
    p_edges, s_edges = np.linspace(-180, 180, round(360 / cell) + 1), np.linspace(-90, 90, round(180 / cell) + 1)
    p_mid, s_mid = 0.5 * (p_edges[1:] + p_edges[:-1]), 0.5 * (s_edges[1:] + s_edges[:-1])
    cells = _reach_map(system, patient, target, p_mid, s_mid, margin)
    area = np.diff(np.sin(np.radians(s_edges)))[None, :] * np.ones((len(p_mid), 1))
    weight = (cells.reachable * area).ravel()
    if not weight.sum():
        raise DatasetError(f"prior 'reachable-sphere' cannot be met: no view of the target {target.tolist()} m is "
                           f"reachable on a {cell:g} deg grid")
    weight /= weight.sum()

    def propose(count):
        c = rng.choice(len(weight), size=count, p=weight)
        i, j = np.unravel_index(c, cells.reachable.shape)
        p = p_edges[i] + cell * rng.random(count)
        lo, hi = np.sin(np.radians(s_edges[j])), np.sin(np.radians(s_edges[j + 1]))
        s = np.degrees(np.arcsin(lo + (hi - lo) * rng.random(count)))
        t = target + jitter * (2.0 * rng.random((count, 3)) - 1.0)
        out = search(system, patient, t, directions(patient, p, s), margin)
        return out.reachable, out.binding, np.full(count, "", dtype=object), out.q, np.column_stack((p, s))

    (Q, nominal), tally = _rounds(n, propose, "reachable-sphere")
    notes = (f"{int(cells.reachable.sum())} of {cells.reachable.size} cells of {cell:g} deg reachable at the target "
             f"({cells.fraction:.1%}); cells unreachable at their centre are not proposed",)
    params = {"cell_deg": cell, "jitter_mm": jitter * 1e3, "target_m": target.tolist()}
    return Q, np.full(len(Q), "", dtype=object), nominal, tally.rejections(notes), params


#: Frames per sweep of the ``sweep`` prior by default.
SWEEP_VIEWS = 50


#: The sweep prior gives up when none of its first this many proposals fits (10): the target is jittered by at
#: most ``jitter_mm``, so a sweep that fails ten times around it is no matter of luck (a hang of 900 s before).
SWEEP_GIVE_UP = 10


def _sweep_parameters(patient, arc_deg=190.0, n_views=SWEEP_VIEWS, jitter_mm=20.0, target_m=None):
    """(arc deg, frames, jitter m, target) of the sweep prior, checked."""
    return (_number(arc_deg, "arc_deg", 1e-3, 360.0, "deg"), _integer(n_views, "n_views", 2, 10_000),
            _number(jitter_mm, "jitter_mm", 0.0, 500.0, "mm") / 1e3, _target(target_m, patient))


def sweep(system, patient, rng, n, margin, shard=0, *, arc_deg=190.0, n_views=SWEEP_VIEWS, jitter_mm=20.0,
          target_m=None):
    """Sweeps labelled ``"sweep K.I"``: the I-th proposal of shard K (unique across the shards of a dataset)."""
    from carmkin.sweeps import plan_sweep

    arc, views, jitter, target = _sweep_parameters(patient, arc_deg, n_views, jitter_mm, target_m)
    tally, kept, failures = _Tally(), [], []
    while tally.accepted < n:
        if tally.proposed >= MAX_PROPOSAL_FACTOR * math.ceil(n / views) + MAX_PROPOSAL_FACTOR or (
                not kept and tally.proposed >= SWEEP_GIVE_UP):
            raise DatasetError(f"prior 'sweep' cannot be met: {len(kept)} of {tally.proposed} sweeps of "
                               f"{arc:g} deg fit around {target.tolist()} m ({'; '.join(failures[:2])}); try a "
                               "smaller --arc-deg or another --target-mm")
        t = target + jitter * (2.0 * rng.random(3) - 1.0)
        planned = plan_sweep(system, t, arc, views, patient, margin=margin)
        index = tally.proposed
        tally.add(np.array([planned.success]), np.array(["sweep failed"], dtype=object), np.array([""], dtype=object))
        if planned.success:
            kept.append((np.asarray(planned.q), np.full(views, f"sweep {shard}.{index}", dtype=object)))
        else:
            failures.append(str(getattr(planned.failure, "reason", planned.failure)))
        tally.accepted = sum(len(q) for q, _ in kept)
    Q = np.concatenate([q for q, _ in kept])[:n]
    labels = np.concatenate([g for _, g in kept])[:n]
    swept = sum(1 for _ in kept)
    notes = (f"{swept} of {tally.proposed} sweeps planned ({views} frames each"
             + (f"; the last cut to {n % views} frames: n = {n} is no multiple of n_views)" if n % views else ")"),)
    rejections = Rejections(tally.proposed, swept, dict(tally.reasons), {}, notes)
    params = {"arc_deg": arc, "n_views": views, "jitter_mm": jitter * 1e3, "target_m": target.tolist()}
    return Q, labels, np.full((len(Q), 2), np.nan), rejections, params


def joint_uniform(system, patient, rng, n, margin):
    from .samples import clearance

    lower, upper = system.lower, system.upper

    def propose(count):
        Q = lower + (upper - lower) * rng.random((count, system.nq))
        keep = clearance(system, patient, Q) >= margin
        return keep, np.full(count, "contact", dtype=object), np.full(count, "", dtype=object), Q

    (Q,), tally = _rounds(n, propose, "joint-uniform")
    return Q, np.full(len(Q), "", dtype=object), np.full((len(Q), 2), np.nan), tally.rejections(), {}


DRAW = {"standard-views": standard_views, "reachable-sphere": reachable_sphere, "sweep": sweep,
        "joint-uniform": joint_uniform}


def check_whole_groups(prior: str, parameters: dict, n: int, shard_size: int) -> None:
    """A dataset of the ``sweep`` prior holds whole sweeps, none cut at a shard's end: ``shard_size`` and
    ``n`` multiples of ``n_views``, or :class:`DatasetError` naming them and the nearest that are."""
    if prior != "sweep":
        return
    views = _integer(parameters.get("n_views", SWEEP_VIEWS), "n_views", 2, 10_000)
    for name, value in (("shard_size", shard_size), ("n", n)):
        if value % views:
            lower, upper = max(views, value // views * views), (value // views + 1) * views
            raise DatasetError(f"{name} = {value} is no multiple of n_views = {views}: a sweep would be cut "
                               f"{'at a shard boundary' if name == 'shard_size' else 'at the end'}; use "
                               f"{name} = {lower}" + (f" or {upper}" if upper != lower else ""))


#: Each prior's parameter check (its parameters' values, without drawing).
CHECK = {"standard-views": _standard_views_parameters, "reachable-sphere": _reachable_sphere_parameters,
         "sweep": _sweep_parameters, "joint-uniform": lambda patient: ()}


def check_values(prior: str, given: dict, patient=None) -> None:
    """:class:`DatasetError` naming any of ``given`` that ``prior`` does not take or whose value it refuses
    (unknown view names, angles out of range, ...): every parameter checked before any work."""
    check_parameters(prior, given)
    CHECK[prior](patient, **given)


def check_prior(prior) -> str:
    """``prior`` as one of :data:`PRIORS`, or :class:`DatasetError` naming them."""
    if not isinstance(prior, str) or prior not in DRAW:
        raise DatasetError(f"prior must be one of {', '.join(PRIORS)}, got {prior!r}")
    return prior


def parameters(prior: str) -> tuple[str, ...]:
    """The names of ``prior``'s own parameters."""
    import inspect

    return tuple(p.name for p in inspect.signature(DRAW[prior]).parameters.values() if p.kind is p.KEYWORD_ONLY)


def check_parameters(prior: str, given) -> None:
    """:class:`DatasetError` naming any of ``given`` that ``prior`` does not take."""
    unknown = sorted(set(given) - set(parameters(prior)))
    if unknown:
        raise DatasetError(f"prior {prior!r} takes {', '.join(parameters(prior)) or 'no parameters'}, got "
                           f"{', '.join(unknown)}")
