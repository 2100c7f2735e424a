"""The per-preset acceptance of issue 30: every planner on one preset, with its numbers (SI units inside).

One function per check, each returning data (the benchmark ``benchmarks/presets_acceptance.py`` prints them,
one row per preset; ``tests/studies/test_presets_acceptance.py`` checks them against independent oracles):

- :func:`zero_view`: the preset's own zero view — AP (primary 0°, secondary 0°) through the table origin, no
  patient — planned, or a :class:`~carmkin.errors.PresetError` naming why the chain cannot reach it;
- :func:`fk_agreement`: closed-form FK vs Pinocchio (:func:`carmkin.robot.verify.verify`), worst error (m or rad);
- :func:`standard_views`: the named standard views (:data:`carmkin.views.standard.STANDARD_VIEWS`) planned through
  the isocentre with a parametric patient on the table, each plan or the reason it is unreachable;
- :func:`reach`: the reach map of the isocentre with that patient (91 × 46 cells at 2°: primary −90…90°,
  secondary −45…45°) and its time;
- :func:`cbct_sweep`: the family's cone-beam CT orbit with that patient, its clearance certified along the arc
  (:func:`carmkin.sweeps.plan_sweep`): :func:`cbct_joint` is the C-arm joint whose axis at rest lies along the
  table (Z0): the orbital joint of a mobile C-arm beside the table (190°, :data:`ARC_DEG`), the angular
  (propeller) joint of an angiography stand at the head end (200°);
- :func:`dicom_round_trip`: XA primary/secondary angles of in-range configurations, turned back into joints by
  planning the view they name (:func:`carmkin.views.plan_view`), and read again: the worst difference (deg).

Frames: the table frame 0 (X0 to the table's left, Y0 down, Z0 to the head); the isocentre is its origin for
every built-in preset (the point of the principal axis at the orbital offset at zero joints).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from carmkin.interop import dicom
from carmkin.model.system import CArmSystem
from carmkin.patient import ParametricPatient
from carmkin.robot.verify import verify
from carmkin.sweeps import plan_sweep
from carmkin.views import View, plan_view, reach_map
from carmkin.views.standard import STANDARD_VIEWS, standard_view
from carmkin.world import World

#: The reach map's grid (deg): 91 primary × 46 secondary angles at 2°.
PRIMARY_DEG = np.arange(-90, 91, 2)
SECONDARY_DEG = np.arange(-45, 46, 2)
#: The cone-beam CT arc (deg) of each family, by the joint that turns it (:func:`cbct_joint`).
ARC_DEG = {"orbital": 190.0, "angular": 200.0}
#: A joint axis counts as along the table when |cos| of its angle to Z0 is at least this.
ALONG_TABLE_COS = 1.0 - 1e-9
#: Configurations of :func:`dicom_round_trip` are drawn until their clearance to the table and floor is at least
#: this (m): the plan then keeps the configuration's own roll and distance free of contact.
ROUND_TRIP_CLEARANCE = 0.05


def cbct_joint(system: CArmSystem) -> str:
    """``"orbital"`` or ``"angular"``: the C-arm joint whose axis lies along the table axis Z0 at rest (all
    joints 0), i.e. the rotation about the patient's long axis that a cone-beam CT orbit uses. A
    :class:`ValueError` subclass (:class:`carmkin.errors.SweepError`) when neither does."""
    from carmkin.errors import SweepError

    frames = system.dh_frames(np.zeros(system.nq))  # joint i of the paper's chain turns about Z of DH frame i
    for name, frame in (("orbital", 4), ("angular", 3)):
        if abs(frames[frame][2, 2]) >= ALONG_TABLE_COS:
            return name
    raise SweepError(f"system {system.name!r}: neither the orbital nor the angular axis lies along the table at rest")


def family(system: CArmSystem) -> str:
    """``"robot-held"`` for a C-arm a robot carries (mount joints); ``"angiography"`` for a stand whose
    isocentre is fixed to the room (vertical and horizontal travel locked: the table moves instead), whether
    at the head end (its CBCT orbit the propeller) or a biplane's lateral plane; else ``"mobile"``."""
    if system.mount.joints:
        return "robot-held"
    return "angiography" if system.carm.vertical.locked and system.carm.horizontal.locked else "mobile"


def patient_on(system: CArmSystem) -> ParametricPatient:
    """The acceptance's patient: 1.75 m, 75 kg, HFS, chest at the isocentre, lying on the table top."""
    return ParametricPatient.on_table(system)


def zero_view(system: CArmSystem):
    """The plan (:class:`carmkin.views.ViewPlan`) of the preset's zero view: AP (primary 0°, secondary 0°) of an
    HFS patient through the table origin — the isocentre at rest — with the table and no patient. A preset whose
    chain cannot reach it (joint ranges that exclude it, a body in the way) is a
    :class:`~carmkin.errors.PresetError` naming the preset and the planner's reason (the joints and ranges)."""
    from carmkin.errors import PresetError

    plan = plan_view(system, View.from_angles(0.0, 0.0, np.zeros(3)))
    if not plan.success:
        raise PresetError(f"preset {system.name!r}: the chain cannot reach its own zero view (AP, primary 0° and "
                          f"secondary 0°, through the table origin): {plan.reason}")
    return plan


def fk_agreement(system: CArmSystem, samples: int = 10_000, seed: int = 0) -> float:
    """Worst difference (m or rad) of every frame between the closed form and Pinocchio over ``samples``
    random configurations, in and beyond the limits."""
    return verify(system, samples, seed=seed).worst


@dataclass(frozen=True)
class StandardViews:
    """The plan of each named standard view (name → :class:`carmkin.views.ViewPlan`) and the time (s)."""

    plans: dict
    seconds: float

    @property
    def planned(self) -> int:
        return sum(plan.success for plan in self.plans.values())

    def unreachable(self) -> dict[str, str]:
        """Name → the reason (``ViewPlan.reason``) of each view not planned."""
        return {name: str(plan.reason) for name, plan in self.plans.items() if not plan.success}


def standard_views(system: CArmSystem, patient=None) -> StandardViews:
    """Every named standard view through the isocentre (table origin) planned with ``patient`` (default
    :func:`patient_on`)."""
    patient = patient_on(system) if patient is None else patient
    start = time.perf_counter()
    plans = {name: plan_view(system, standard_view(name, position=patient), patient=patient) for name in STANDARD_VIEWS}
    return StandardViews(plans, time.perf_counter() - start)


@dataclass(frozen=True)
class Reach:
    """A reach map (:class:`carmkin.views.ReachMap`) and its wall time (s)."""

    map: object
    seconds: float


def reach(system: CArmSystem, patient=None, primary_deg=PRIMARY_DEG, secondary_deg=SECONDARY_DEG,
          workers: int = 1) -> Reach:
    """The reach map of the isocentre over ``primary_deg`` × ``secondary_deg`` with ``patient`` (default
    :func:`patient_on`), timed."""
    patient = patient_on(system) if patient is None else patient
    start = time.perf_counter()
    out = reach_map(system, np.zeros(3), primary_deg, secondary_deg, patient=patient, workers=workers)
    return Reach(out, time.perf_counter() - start)


def cbct_sweep(system: CArmSystem, patient=None, views: int = 100):
    """The family's CBCT orbit (:func:`cbct_joint`, :data:`ARC_DEG`) of ``views`` frames about the isocentre
    with ``patient`` (default :func:`patient_on`): a :class:`carmkin.sweeps.Sweep` whose ``min_clearance`` is
    certified over the whole arc."""
    patient = patient_on(system) if patient is None else patient
    joint = cbct_joint(system)
    q_start = None
    if system.mount.joints:  # a robot holds the C: start at the AP view's plan, the sweep joint at its lower limit
        from carmkin.views import View, plan_view

        index = system.joint_names.index(joint)
        q_start = plan_view(system, View.from_angles(0.0, 0.0, np.zeros(3)), patient).q.copy()
        q_start[index] = system.lower[index]
    return plan_sweep(system, np.zeros(3), ARC_DEG[joint], views, patient=patient, q_start=q_start, joint=joint)


def in_range_configurations(system: CArmSystem, n: int, seed: int = 0, clearance: float = ROUND_TRIP_CLEARANCE):
    """``n`` configurations (n, nq) uniform within the joint ranges whose every pair is at least ``clearance``
    (m) apart."""
    rng = np.random.default_rng(seed)
    world = World(system)
    out = []
    while len(out) < n:
        Q = rng.uniform(system.lower, system.upper, size=(4 * n, system.nq))
        out.extend(Q[world.clearance(Q) >= clearance])
    return np.array(out[:n])


@dataclass(frozen=True)
class RoundTrip:
    """``worst_deg``: the largest difference of the primary or secondary angle (deg) after the round trip;
    ``planned``: configurations whose view was planned of ``count``."""

    worst_deg: float
    planned: int
    count: int


def dicom_round_trip(system: CArmSystem, n: int = 50, seed: int = 0, position: str = "HFS") -> RoundTrip:
    """Joints → XA angles → joints → XA angles on ``n`` in-range configurations: the angles of each source pose
    (:func:`carmkin.interop.dicom.xa_angles`), the view they name through the configuration's isocentre (its
    point of the principal axis at the orbital offset) planned on the system (:func:`plan_view`, no
    patient), and the angles of the planned pose."""
    worst, planned = 0.0, 0
    Q = in_range_configurations(system, n, seed)
    for q in Q:
        T = system.fk(q)
        primary, secondary, _ = dicom.xa_angles(T, position)
        if abs(abs(secondary) - 90.0) < 1e-6:  # the primary angle is undefined there
            continue
        iso = T[:3, 3] + system.carm.orbital_offset * T[:3, 2]
        plan = plan_view(system, View.from_angles(primary, secondary, iso, position), q_current=q, nearest=False, motion_plan=False)
        if not plan.success:
            continue
        planned += 1
        back = dicom.xa_angles(system.fk(plan.q), position)
        worst = max(worst, angle_difference_deg(back[0], primary), angle_difference_deg(back[1], secondary))
    return RoundTrip(worst, planned, len(Q))


def angle_difference_deg(a: float, b: float) -> float:
    """|a − b| (deg) wrapped into [0, 180]."""
    return abs(math.remainder(a - b, 360.0))
