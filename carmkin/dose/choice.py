"""Dose-aware choice of a view: among the reachable views within an angular tolerance of a requested one, the
one whose run gives the smallest predicted peak skin dose given the events so far, and the certified motion to it.

The candidates are the cells of a reach map (:func:`carmkin.views.reach_map`, clearance ≥ the margin at the
configuration) on a grid of XA angles about the request's (steps of ``step_deg``), kept where the angle between
their beam and the request's is at most ``tolerance_deg``; each is scored by the PSD of the events so far plus
its predicted run (:mod:`carmkin.dose.plan`); the least wins (ties: the nearer to the request). The report gives
the PSD with the chosen view and with the requested one, and, from ``q_current``, the motion to the chosen
configuration planned and certified by :func:`carmkin.motion.plan_motion` (keeping
:data:`carmkin.views.plan.PATH_CLEARANCE`, as :func:`carmkin.views.plan_view` does).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin.dose.compute import event_dose
from carmkin.dose.event import Event
from carmkin.dose.plan import Technique, central_ray, water_thickness
from carmkin.dose.skin import DEFAULT_SPACING, skin_of
from carmkin.errors import DoseError
from carmkin.validation import real_array, real_scalar

#: Default angular tolerance (deg) between a request and its dose-aware alternatives (the issue's 10°).
DEFAULT_TOLERANCE_DEG = 10.0
#: Angles (deg) a beam may exceed the tolerance by and still count as within it (round-off of the grid's angles).
ANGLE_TOLERANCE_DEG = 1e-9
#: A candidate this close (deg) to the request is the requested view itself (arccos's round-off near 0).
SAME_BEAM_DEG = 1e-4


@dataclass(frozen=True)
class Candidates:
    """The reachable alternatives of a request: ``primary_deg``, ``secondary_deg``, ``angle_deg`` (to the request)
    and ``q`` (k, nq), nearest first; ``requested`` the index of the request itself (or None: unreachable)."""

    primary_deg: np.ndarray
    secondary_deg: np.ndarray
    angle_deg: np.ndarray
    q: np.ndarray
    requested: int | None
    checked: int


@dataclass(frozen=True)
class Choice:
    """A dose-aware choice: the chosen candidate's ``primary_deg``, ``secondary_deg``, ``angle_deg`` from the
    request and joints ``q``; ``event`` its predicted run; ``psd_chosen_gy`` the PSD after it, ``psd_requested_gy``
    after the requested view instead (None: the request is unreachable), ``psd_before_gy`` before the run;
    ``motion`` the certified :class:`carmkin.motion.Trajectory` from ``q_current`` (None without one);
    ``scores_gy`` (k,) every candidate's PSD."""

    primary_deg: float
    secondary_deg: float
    angle_deg: float
    q: np.ndarray
    event: object
    psd_chosen_gy: float
    psd_requested_gy: float | None
    psd_before_gy: float
    motion: object
    scores_gy: np.ndarray


def candidates(system, view, patient, tolerance_deg: float = DEFAULT_TOLERANCE_DEG, step_deg: float | None = None,
               margin: float | None = None) -> Candidates:
    """The reachable views within ``tolerance_deg`` of ``view`` (a :class:`carmkin.views.View`) for ``patient``:
    a reach map on XA angles about the request's in steps of ``step_deg`` (default half the tolerance)."""
    from carmkin.views import View, reach_map
    from carmkin.world import DEFAULT_MARGIN

    if not isinstance(view, View):
        raise DoseError(f"view must be a carmkin.views.View, got {type(view).__name__}")
    tol = real_scalar(tolerance_deg, "tolerance_deg", error=DoseError, low=0.0, high=45.0, unit="deg")
    step = tol / 2 if step_deg is None else real_scalar(step_deg, "step_deg", error=DoseError, low=0.1, high=45.0,
                                                        unit="deg")
    if step <= 0.0:  # a zero tolerance: the request only
        offsets = np.zeros(1)
    else:
        n = int(math.floor(tol / step * math.sqrt(2) + 1e-9)) + 1  # a secondary offset shrinks a primary one's angle
        offsets = step * np.arange(-n, n + 1)
    p0, s0 = view.angles(patient)
    primary = np.clip(p0 + offsets, -180.0, 180.0)
    secondary = np.clip(s0 + offsets, -90.0, 90.0)
    m = reach_map(system, view.target, np.unique(primary), np.unique(secondary), patient,
                  margin=DEFAULT_MARGIN if margin is None else margin)
    angle = np.degrees(np.arccos(np.clip(m.directions @ view.axis, -1.0, 1.0)))
    keep = m.reachable & (angle <= tol + ANGLE_TOLERANCE_DEG)
    P, S = np.meshgrid(m.primary_deg, m.secondary_deg, indexing="ij")
    order = np.argsort(angle[keep], kind="stable")
    a = angle[keep][order]
    requested = 0 if len(a) and a[0] <= SAME_BEAM_DEG else None
    return Candidates(P[keep][order], S[keep][order], a, m.q[keep][order], requested, int(np.count_nonzero(
        angle <= tol + ANGLE_TOLERANCE_DEG)))


class _Running:
    """The dose so far on the skin cells (and the skin's columns, for the events' beams)."""

    def __init__(self, system, patient, skin, events) -> None:
        self.system, self.skin = system, skin
        self.columns = np.ascontiguousarray(skin.points.T)
        self.dose = np.zeros(len(skin.points))
        for i, e in enumerate(events):
            if not isinstance(e, Event):
                raise DoseError(f"events[{i}] must be a carmkin.dose.Event, got {type(e).__name__}")
            self.add(e)

    def part(self, event):
        return event_dose(self.system, event, self.skin, self.columns)

    def add(self, event) -> None:
        p = self.part(event)
        self.dose[p.cells] += p.dose_gy

    def psd_with(self, event) -> float:
        p = self.part(event)
        if not len(p.cells):
            return float(self.dose.max(initial=0.0))
        return float(max(self.dose.max(initial=0.0), (self.dose[p.cells] + p.dose_gy).max()))


def _predicted(system, patient, technique: Technique, q, name: str):
    k = technique.kerma_per_frame(water_thickness(patient, *central_ray(system, q)))
    return technique.event(q, k * technique.frames, name=name)


def _check(system, patient, technique) -> Technique:
    from carmkin.model.system import require_system

    require_system(system, DoseError)
    technique = Technique() if technique is None else technique
    if not isinstance(technique, Technique):
        raise DoseError(f"technique must be a carmkin.dose.Technique, got {type(technique).__name__}")
    from carmkin.patient import ParametricPatient

    if not isinstance(patient, ParametricPatient):
        raise DoseError(f"patient must be a carmkin.patient.ParametricPatient, got {type(patient).__name__}")
    patient.check_placement(system, "patient")
    return technique


def _joints(system, q, name: str) -> np.ndarray | None:
    return None if q is None else real_array(q, name, (system.nq,), error=DoseError, unit="m, rad")


def _choose(system, patient, technique, running: _Running, cands: Candidates, q_current, name: str) -> Choice:
    if not len(cands.q):
        raise DoseError(f"no reachable view within the tolerance of the request {name!r} "
                        f"({cands.checked} directions checked)")
    events = [_predicted(system, patient, technique, q, name) for q in cands.q]
    scores = np.array([running.psd_with(e) for e in events])
    best = int(np.argmin(scores))  # candidates are nearest first: a tie goes to the nearer
    motion = None
    if q_current is not None:
        from carmkin.motion import MotionPlanner
        from carmkin.views.plan import PATH_CLEARANCE, world_for

        from carmkin.errors import MotionPlanError

        planner = MotionPlanner(system, margin=PATH_CLEARANCE, world=world_for(system, patient))
        try:
            motion = planner.plan(q_current, cands.q[best])
        except MotionPlanError as exc:  # a start closer than the path clearance to something: no motion, and why
            motion = planner.failed(q_current, str(exc))
    return Choice(float(cands.primary_deg[best]), float(cands.secondary_deg[best]), float(cands.angle_deg[best]),
                  cands.q[best].copy(), events[best], float(scores[best]),
                  None if cands.requested is None else float(scores[cands.requested]),
                  float(running.dose.max(initial=0.0)), motion, scores)


def choose_view(system, view, patient, events=(), technique: Technique | None = None, *,
                tolerance_deg: float = DEFAULT_TOLERANCE_DEG, step_deg: float | None = None, q_current=None,
                spacing: float = DEFAULT_SPACING) -> Choice:
    """The dose-aware alternative of ``view`` (a :class:`carmkin.views.View`) for a run of ``technique`` on
    ``patient`` (a parametric patient on the table top), given ``events`` so far (:class:`carmkin.dose.Event`),
    among the reachable views within ``tolerance_deg``; with ``q_current`` (nq,), the certified motion there."""
    technique = _check(system, patient, technique)
    q_current = _joints(system, q_current, "q_current")
    if isinstance(events, (str, bytes)) or not hasattr(events, "__iter__"):
        raise DoseError(f"events must be a sequence of carmkin.dose.Event, got {type(events).__name__}")
    running = _Running(system, patient, skin_of(patient, spacing), list(events))
    return _choose(system, patient, technique, running, candidates(system, view, patient, tolerance_deg, step_deg),
                   q_current, view.name)


@dataclass(frozen=True)
class Procedure:
    """A dose-aware procedure: ``choices`` (one :class:`Choice` per requested run, each given the chosen runs
    before it), ``psd_requested_gy`` (every run at its requested view) and ``psd_chosen_gy`` (the chosen
    views), ``reduction`` = 1 − chosen / requested, and the two maps ``requested_map``, ``chosen_map``."""

    choices: tuple
    psd_requested_gy: float
    psd_chosen_gy: float
    reduction: float
    requested_map: object
    chosen_map: object


def dose_aware_procedure(system, requests, patient, technique: Technique | None = None, *,
                         tolerance_deg: float = DEFAULT_TOLERANCE_DEG, step_deg: float | None = None, q_start=None,
                         spacing: float = DEFAULT_SPACING) -> Procedure:
    """Run ``requests`` (a sequence of :class:`carmkin.views.View`, one run each) dose-aware: each run at the
    alternative that minimizes the PSD given the chosen runs before it, moving from ``q_start`` (nq,) (or
    without motion when None) from one chosen configuration to the next; compared with every run at its
    requested view (which must be reachable)."""
    from carmkin.dose.compute import skin_dose

    technique = _check(system, patient, technique)
    requests = list(requests)
    if not requests:
        raise DoseError("requests must hold at least one view, got none")
    skin = skin_of(patient, spacing)
    running = _Running(system, patient, skin, [])
    cache, choices, requested_events = {}, [], []
    q = _joints(system, q_start, "q_start")
    for i, view in enumerate(requests):
        key = (view.target, view.direction)
        if key not in cache:
            cache[key] = candidates(system, view, patient, tolerance_deg, step_deg)
        cands = cache[key]
        if cands.requested is None:
            raise DoseError(f"requests[{i}] ({view.name or 'unnamed'}) is not reachable: plan a reachable view")
        choice = _choose(system, patient, technique, running, cands, q, view.name or f"run {i}")
        running.add(choice.event)
        choices.append(choice)
        requested_events.append(_predicted(system, patient, technique, cands.q[cands.requested], f"requested {i}"))
        q = None if q is None else choice.q
    requested = skin_dose(system, requested_events, skin)
    chosen = skin_dose(system, [c.event for c in choices], skin)
    return Procedure(tuple(choices), requested.psd_gy, chosen.psd_gy,
                     1.0 - chosen.psd_gy / requested.psd_gy if requested.psd_gy > 0 else 0.0, requested, chosen)
