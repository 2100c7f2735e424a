"""The predicted skin dose of a plan: planned views, sweeps or joint configurations with a stated technique.

A plan has no recorded air kerma, so this module states a model of it, written once (docs/dose.md, "From a
plan"): the X-ray system's automatic exposure control (AEC) holds the detector's signal per frame, so the air
kerma at the IRP per frame grows exponentially with the water-equivalent thickness ``t`` the central ray
crosses in the patient:

    K_IRP per frame = K_ref × exp(μ_w (t − t_ref))

- ``t``: the chord of the central ray (source to detector) through the parametric body's segments, each
  weighted by its density over water's (Winter's segment densities, :data:`carmkin.patient.body.DENSITIES`;
  where segments overlap, the denser counts once): :func:`water_thickness`. For a CT patient
  (:class:`carmkin.patient.CTPatient`), the chord inside its closed skin surface, the body taken as water (the
  CT's HU are not kept: lungs and bone are not resolved).
- ``μ_w``: the linear attenuation coefficient of water at the beam's effective energy, the monoenergetic energy
  whose half-value layer in aluminium is the beam's (its kVp and filter's HVL, :mod:`carmkin.dose.coefficients`):
  :func:`water_attenuation`, from the NIST mass attenuation coefficients of aluminium and water
  (:data:`NIST_ENERGIES_KEV`, :data:`NIST_MU_RHO_AL`, :data:`NIST_MU_RHO_WATER`), narrow beam.
- ``K_ref``, ``t_ref``: the air kerma per frame at the IRP at a reference thickness
  (:data:`REFERENCE_KERMA_GY`, :data:`REFERENCE_THICKNESS_M`; a technique may state its own).

Lengths in m, kerma in Gy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from carmkin.dose import coefficients
from carmkin.dose.event import Event
from carmkin.errors import DoseError
from carmkin.validation import integer, real_array, real_scalar

# source: J. H. Hubbell and S. M. Seltzer, "Tables of X-Ray Mass Attenuation Coefficients and Mass Energy-Absorption
# Coefficients", NIST Standard Reference Database 126 (NISTIR 5632, 1995/2004), tables 3 (aluminium, Z = 13) and 4
# (water, liquid): μ/ρ (cm²/g, coherent scattering included) at these photon energies (keV)
NIST_ENERGIES_KEV = (15.0, 20.0, 30.0, 40.0, 50.0, 60.0, 80.0, 100.0, 150.0)
NIST_MU_RHO_AL = (7.955, 3.441, 1.128, 0.5685, 0.3681, 0.2778, 0.2018, 0.1704, 0.1378)
NIST_MU_RHO_WATER = (1.673, 0.8096, 0.3756, 0.2683, 0.2269, 0.2059, 0.1837, 0.1707, 0.1505)
#: Density of aluminium (g/cm³) and of water (kg/m³).
# source: NIST SRD 126 table 1 (aluminium 2.699 g/cm³); water 1000 kg/m³ (the reference of "water-equivalent")
DENSITY_AL_G_CM3 = 2.699
DENSITY_WATER_KG_M3 = 1000.0
#: Air kerma per frame at the IRP (Gy) the AEC gives at :data:`REFERENCE_THICKNESS_M` of water: an order-of-magnitude
#: anchor for a cine frame, within the 19–589 µGy per frame (entrance surface air kerma, 16–28 cm PMMA) measured on
#: a cardiac flat-detector system by Vano et al.; predicted doses scale with it, the dose-aware comparisons of
#: :mod:`carmkin.dose.choice` (ratios) do not. A technique states its own for a calibrated system.
# source: E. Vano et al., "Dynamic flat panel detector versus image intensifier in cardiac imaging: dose and image
# quality", Phys. Med. Biol. 50 (2005) 5731 (doi:10.1088/0031-9155/50/23/022), abstract: 19-589 µGy/frame (cine)
REFERENCE_KERMA_GY = 1.0e-4
#: Water-equivalent thickness (m) at which the AEC gives :data:`REFERENCE_KERMA_GY` (a 20 cm water patient).
# source: the 20 cm PMMA "standard patient" of Vano et al. 2005 (their phantoms: 16, 20, 24, 28 cm), taken as water
REFERENCE_THICKNESS_M = 0.20
#: Relative round-off allowed at the NIST table's ends (an HVL computed from an end row is inside the table).
TABLE_EDGE = 1e-12
#: Two crossings of a surface by a ray closer than this (m) are one (a ray through an edge or a vertex meets every
#: triangle there).
SAME_CROSSING = 1e-9
#: Frames a run may state (a guard against a unit slip: frames, not milliseconds).
MAX_FRAMES = 10000


def _loglog(x: float, xs, ys) -> float:
    """Interpolate ``ys`` at ``x`` linearly in log-log (``xs`` increasing)."""
    lx, lxs, lys = math.log(x), np.log(xs), np.log(ys)
    return float(math.exp(np.interp(lx, lxs, lys)))


def effective_energy_kev(hvl_mm_al) -> float:
    """The monoenergetic energy (keV) whose half-value layer in aluminium is ``hvl_mm_al`` (mm):
    μ/ρ_Al(E) = ln 2 / (HVL ρ_Al), inverted on the NIST table (log-log)."""
    hvl = real_scalar(hvl_mm_al, "hvl_mm_al", error=DoseError, low=0.1, high=30.0, unit="mm Al")
    mu_rho = math.log(2.0) / (hvl / 10.0 * DENSITY_AL_G_CM3)
    lo, hi = NIST_MU_RHO_AL[-1], NIST_MU_RHO_AL[0]
    if not lo * (1 - TABLE_EDGE) <= mu_rho <= hi * (1 + TABLE_EDGE):
        raise DoseError(f"hvl_mm_al {hvl:g} mm Al is outside the NIST table's {NIST_ENERGIES_KEV[0]:g}-"
                        f"{NIST_ENERGIES_KEV[-1]:g} keV")
    return _loglog(mu_rho, NIST_MU_RHO_AL[::-1], NIST_ENERGIES_KEV[::-1])


def water_attenuation(hvl_mm_al) -> float:
    """Linear attenuation coefficient (1/m) of water at the effective energy of a beam of ``hvl_mm_al``."""
    e = effective_energy_kev(hvl_mm_al)
    return _loglog(e, NIST_ENERGIES_KEV, NIST_MU_RHO_WATER) * DENSITY_WATER_KG_M3 / 10.0  # cm²/g × g/cm³ /cm -> /m


@dataclass(frozen=True)
class Technique:
    """The technique of a planned run: tube voltage ``kvp`` (kV), ``frames`` per run, added ``filter``
    (``{"Cu": mm, "Al": mm}``), collimated ``field_mm = (w, h)`` at the detector (mm), optional ``hvl_mm_al``
    (else from the HVL table), and the AEC's ``reference_kerma_gy`` per frame at ``reference_thickness_m``
    of water (default :data:`REFERENCE_KERMA_GY` at :data:`REFERENCE_THICKNESS_M`)."""

    kvp: float = 80.0
    frames: int = 1
    filter: dict = field(default_factory=lambda: {"Cu": 0.3})
    field_mm: tuple[float, float] = (200.0, 200.0)
    hvl_mm_al: float | None = None
    reference_kerma_gy: float = REFERENCE_KERMA_GY
    reference_thickness_m: float = REFERENCE_THICKNESS_M

    def __post_init__(self) -> None:
        frames = integer(self.frames, "frames", low=1, high=MAX_FRAMES, error=DoseError)
        object.__setattr__(self, "frames", frames)
        object.__setattr__(self, "reference_kerma_gy", real_scalar(
            self.reference_kerma_gy, "reference_kerma_gy", error=DoseError, low=0.0, high=1.0, unit="Gy"))
        object.__setattr__(self, "reference_thickness_m", real_scalar(
            self.reference_thickness_m, "reference_thickness_m", error=DoseError, low=0.0, high=1.0, unit="m"))
        probe = self.event(np.zeros(1), 0.0)  # kVp, filter, field and HVL checked once, as an Event checks them
        object.__setattr__(self, "kvp", probe.kvp)
        object.__setattr__(self, "filter", dict(probe.filter))
        object.__setattr__(self, "field_mm", probe.field_mm)

    def hvl(self) -> float:
        """The beam's HVL (mm Al): stated, or from the HVL table at its kVp and filter."""
        if self.hvl_mm_al is not None:
            return self.hvl_mm_al
        return coefficients.half_value_layer(self.kvp, self.filter["Cu"], self.filter["Al"])

    def kerma_per_frame(self, thickness_m) -> float:
        """Air kerma (Gy) at the IRP per frame for a water-equivalent thickness ``thickness_m`` (m)."""
        t = real_scalar(thickness_m, "thickness_m", error=DoseError, low=0.0, high=2.0, unit="m")
        return self.reference_kerma_gy * math.exp(water_attenuation(self.hvl()) * (t - self.reference_thickness_m))

    def event(self, q, k_irp_gy: float, name: str = "", frames: int | None = None) -> Event:
        """The :class:`Event` of one run at joints ``q`` with air kerma ``k_irp_gy`` (Gy, the whole run)."""
        return Event(q, self.kvp, k_irp_gy, self.field_mm, dict(self.filter), hvl_mm_al=self.hvl_mm_al, name=name)


# --- the central ray through the body ------------------------------------------------------------------------------
def _box_interval(p, d, centre, half) -> tuple[float, float] | None:
    t0, t1 = -math.inf, math.inf
    for k in range(len(p)):
        lo, hi = centre[k] - half[k], centre[k] + half[k]
        if abs(d[k]) < 1e-15:
            if not lo <= p[k] <= hi:
                return None
            continue
        a, b = (lo - p[k]) / d[k], (hi - p[k]) / d[k]
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
    return (t0, t1) if t1 > t0 else None


def _roots(a: float, b: float, c: float) -> tuple[float, float] | None:
    """The interval where a t² + b t + c ≤ 0 (a > 0), or None."""
    disc = b * b - 4 * a * c
    if disc <= 0.0:
        return None
    s = math.sqrt(disc)
    return (-b - s) / (2 * a), (-b + s) / (2 * a)


def _capsule_interval(p, d, a, b, r) -> tuple[float, float] | None:
    """The chord of the line p + t d (|d| = 1) through the capsule a–b of radius r: the capsule is convex, so the
    chord is the hull of the chords through its cylinder and its two end balls."""
    parts = []
    for c in (a, b):
        w = p - c
        parts.append(_roots(1.0, 2 * float(w @ d), float(w @ w) - r * r))
    axis = b - a
    length = float(np.linalg.norm(axis))
    if length > 0:
        u = axis / length
        w = p - a
        dp, wp = d - (d @ u) * u, w - (w @ u) * u
        A = float(dp @ dp)
        if A > 1e-24:
            chord = _roots(A, 2 * float(wp @ dp), float(wp @ wp) - r * r)
        else:
            chord = (-math.inf, math.inf) if float(wp @ wp) < r * r else None
        if chord is not None:
            slab = _box_interval(np.array([float(w @ u)]), np.array([float(d @ u)]), np.array([length / 2]),
                                 np.array([length / 2]))
            if slab is not None:
                lo, hi = max(chord[0], slab[0]), min(chord[1], slab[1])
                parts.append((lo, hi) if hi > lo else None)
    parts = [c for c in parts if c is not None]
    if not parts:
        return None
    return min(c[0] for c in parts), max(c[1] for c in parts)


def surface_chord(vertices: np.ndarray, faces: np.ndarray, start: np.ndarray, end: np.ndarray) -> float:
    """The length (m) of the segment ``start`` → ``end`` inside the closed triangle surface (``vertices`` (N, 3),
    ``faces`` (F, 3)), both ends outside it: the crossings of its triangles (Möller–Trumbore), paired in order."""
    d = end - start
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    e1, e2 = b - a, c - a
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-18
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = start - a
    u = np.einsum("ij,ij->i", s, p) * inv
    qv = np.cross(s, e1)
    v = (qv @ d) * inv
    t = np.einsum("ij,ij->i", e2, qv) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < 1)
    length = float(np.linalg.norm(d))
    crossings = np.sort(t[hit]) * length
    if len(crossings):
        crossings = crossings[np.concatenate(([True], np.diff(crossings) > SAME_CROSSING))]
    if len(crossings) % 2:
        raise DoseError(f"the ray crosses the surface {len(crossings)} times (odd): its ends must lie outside a "
                        "closed surface")
    return float(np.sum(crossings[1::2] - crossings[::2]))


def water_thickness(patient, start, end) -> float:
    """Water-equivalent thickness (m) of ``patient`` (a :class:`carmkin.patient.ParametricPatient`) along the
    segment ``start`` → ``end`` (table frame, m): each segment's chord times its density over water's; where
    chords overlap, the densest segment counts once. For a :class:`carmkin.patient.CTPatient`: the chord inside
    its skin surface (:func:`surface_chord`), the body taken as water."""
    from carmkin.patient import CTPatient, ParametricPatient
    from carmkin.patient.body import DENSITIES, _kind

    if not isinstance(patient, (ParametricPatient, CTPatient)):
        raise DoseError(f"patient must be a carmkin.patient.ParametricPatient or CTPatient (its body gives the "
                        f"water-equivalent thickness of a planned view), got {type(patient).__name__}")
    start = real_array(start, "start", (3,), error=DoseError, unit="m")
    end = real_array(end, "end", (3,), error=DoseError, unit="m")
    length = float(np.linalg.norm(end - start))
    if length <= 0.0:
        raise DoseError("start and end of the ray must differ")
    if isinstance(patient, CTPatient):
        if patient.faces is None:
            raise DoseError("the CT patient has no surface triangles (faces=None): build it with CTPatient.from_ct")
        return surface_chord(patient.surface(), patient.faces, start, end)
    T = patient.pose()
    R, o = T[:3, :3], T[:3, 3]
    p, d = R.T @ (start - o), R.T @ ((end - start) / length)  # the ray in the patient frame
    chords = []
    for s in patient.segments:
        if s.shape == "box":
            c = _box_interval(p, d, np.asarray(s.a), np.asarray(s.extents) / 2)
        else:
            c = _capsule_interval(p, d, np.asarray(s.a, float), np.asarray(s.b, float), s.radius)
        if c is not None and c[1] > 0.0 and c[0] < length:
            chords.append((max(c[0], 0.0), min(c[1], length), DENSITIES[_kind(s)] / DENSITY_WATER_KG_M3))
    cuts = sorted({t for c in chords for t in c[:2]})
    total = 0.0
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        mid = 0.5 * (lo + hi)
        density = max((c[2] for c in chords if c[0] <= mid <= c[1]), default=0.0)
        total += (hi - lo) * density
    return total


def central_ray(system, q) -> tuple[np.ndarray, np.ndarray]:
    """(source, detector centre) of joints ``q`` (table frame, m): the source frame's origin and the point at the
    preset's source–detector distance along its principal axis."""
    T = system.fk(np.asarray(q, dtype=float))
    return T[:3, 3].copy(), T[:3, 3] + system.carm.source_to_detector * T[:3, 2]


# --- a plan as events --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PlanDose:
    """The predicted dose of a plan: ``events`` (one :class:`Event` per run, the predicted ``k_irp_gy``),
    ``water_m`` (per event, the water-equivalent thickness of its central ray, m), ``kerma_per_frame_gy``
    (per event), ``map`` (the :class:`carmkin.dose.DoseMap`) and the ``technique``; for a biplane, ``planes``
    names each event's plane (``"frontal"`` or ``"lateral"``), else it is ``None``."""

    events: tuple
    water_m: np.ndarray
    kerma_per_frame_gy: np.ndarray
    map: object
    technique: Technique
    planes: tuple | None = None


def _runs(system, plan) -> list[tuple[np.ndarray, int | None, str]]:
    """``plan`` as (q, frames or None for the technique's, name) per run: a joint vector (nq,), an (n, nq)
    array (n runs), a successful view plan (``.q``), a sweep (``.q`` (n, nq): n frames of one frame each)."""
    if isinstance(plan, (str, bytes)) or not hasattr(plan, "__iter__"):
        raise DoseError(f"plan must be a sequence of views (plan_view results), sweeps or joint vectors, got "
                        f"{type(plan).__name__}")
    runs = []
    for i, item in enumerate(plan):
        label = f"plan[{i}]"
        if hasattr(item, "angles") and hasattr(item, "q") and np.ndim(getattr(item, "q")) == 2:  # a Sweep
            if not getattr(item, "success", True):
                raise DoseError(f"{label}: the sweep failed ({getattr(item, 'reason', '')}); plan a feasible one")
            Q = real_array(item.q, f"{label}.q", (None, system.nq), error=DoseError, unit="m, rad")
            runs += [(q, 1, f"{label} frame {k}") for k, q in enumerate(Q)]
            continue
        if hasattr(item, "success") and hasattr(item, "q"):  # a view plan
            if not item.success:
                raise DoseError(f"{label}: the view is unreachable ({getattr(item, 'reason', '')}); plan a reachable one")
            name = getattr(getattr(item, "view", None), "name", "") or label
            runs.append((real_array(item.q, f"{label}.q", (system.nq,), error=DoseError, unit="m, rad"), None, name))
            continue
        Q = real_array(item, label, None, error=DoseError, unit="m, rad")
        if Q.ndim == 1 and len(Q) == system.nq:
            runs.append((Q, None, label))
        elif Q.ndim == 2 and Q.shape[1] == system.nq:
            runs += [(q, None, f"{label}[{k}]") for k, q in enumerate(Q)]
        else:
            raise DoseError(f"{label} must be a joint vector ({system.nq},) or ({system.nq},) rows, a view plan or a "
                            f"sweep, got shape {Q.shape}")
    if not runs:
        raise DoseError("plan must hold at least one view, got none")
    return runs


def _biplane_runs(biplane, plan) -> list[tuple[str, np.ndarray, str]]:
    """``plan`` on a biplane as (plane, q of that plane, name) per run: a successful biplane plan (``.q``, both
    planes' views: :func:`carmkin.biplane.plan_biplane`) or a biplane joint vector (nq,) / (n, nq) — each a run of
    both planes."""
    if isinstance(plan, (str, bytes)) or not hasattr(plan, "__iter__"):
        raise DoseError(f"plan must be a sequence of biplane plans (carmkin.biplane.plan_biplane results) or biplane "
                        f"joint vectors, got {type(plan).__name__}")
    runs = []
    for i, item in enumerate(plan):
        label = f"plan[{i}]"
        if hasattr(item, "frontal") and hasattr(item, "lateral") and hasattr(item, "success"):  # a BiplanePlan
            if not item.success:
                raise DoseError(f"{label}: the biplane plan failed ({getattr(item, 'reason', '')}); plan a feasible "
                                "pair")
            Q = real_array(item.q, f"{label}.q", (biplane.nq,), error=DoseError, unit="m, rad")[None]
        elif hasattr(item, "success") or hasattr(item, "q"):
            raise DoseError(f"{label}: a plan of one plane ({type(item).__name__}) on the biplane {biplane.name!r}: "
                            "give biplane plans (carmkin.biplane.plan_biplane) or biplane joint vectors")
        else:
            Q = real_array(item, label, None, error=DoseError, unit="m, rad")
            if Q.ndim == 1:
                Q = Q[None]
            if Q.ndim != 2 or Q.shape[1] != biplane.nq:
                raise DoseError(f"{label} must be a biplane joint vector ({biplane.nq},) or ({biplane.nq},) rows, or "
                                f"a biplane plan, got shape {Q.shape}")
        for k, q in enumerate(Q):
            q_f, q_l = biplane.planes_q(q)
            name = label if len(Q) == 1 else f"{label}[{k}]"
            runs += [("frontal", q_f, f"{name} frontal"), ("lateral", q_l, f"{name} lateral")]
    if not runs:
        raise DoseError("plan must hold at least one view, got none")
    return runs


def _predict(system, plan, patient, technique: Technique | None):
    """(systems, events, water-equivalent thickness (m), air kerma per frame (Gy), planes or None) of ``plan`` on
    ``system`` (a CArmSystem or a Biplane)."""
    from carmkin.model.biplane import Biplane
    from carmkin.model.system import require_system

    technique = Technique() if technique is None else technique
    if not isinstance(technique, Technique):
        raise DoseError(f"technique must be a carmkin.dose.Technique, got {type(technique).__name__}")
    if isinstance(system, Biplane):
        planes = {"frontal": system.frontal, "lateral": system.lateral}
        runs = [(plane, planes[plane], q, None, name) for plane, q, name in _biplane_runs(system, plan)]
    else:
        require_system(system, DoseError)
        runs = [(None, system, q, frames, name) for q, frames, name in _runs(system, plan)]
    systems, events, water, per_frame = [], [], [], []
    for _, plane_system, q, frames, name in runs:
        t = water_thickness(patient, *central_ray(plane_system, q))
        k = technique.kerma_per_frame(t)
        n = technique.frames if frames is None else frames
        systems.append(plane_system)
        events.append(technique.event(q, k * n, name=name))
        water.append(t)
        per_frame.append(k)
    planes = None if runs[0][0] is None else tuple(r[0] for r in runs)
    return systems, events, np.array(water), np.array(per_frame), planes


def predict_events(system, plan, patient, technique: Technique | None = None) -> tuple[list, np.ndarray, np.ndarray]:
    """The predicted events of ``plan`` on one system (see :func:`plan_dose`): (events, water-equivalent thickness
    (m) and air kerma per frame (Gy) of each)."""
    _, events, water, per_frame, _ = _predict(system, plan, patient, technique)
    return events, water, per_frame


def plan_dose(system, plan, patient, technique: Technique | None = None, *, spacing: float | None = None,
              skin=None) -> PlanDose:
    """The predicted skin dose of ``plan`` on ``system`` for ``patient`` (a parametric patient resting on the table
    top, or a :class:`carmkin.patient.CTPatient` placed with ``on_table``: its surface the skin): ``plan`` a
    sequence of view plans (:func:`carmkin.views.plan_view` results), sweeps (:func:`carmkin.sweeps.plan_sweep`,
    one frame per view) or joint vectors (nq,) / (n, nq); each view a run of ``technique.frames`` frames. On a
    biplane (``system`` a :class:`carmkin.model.biplane.Biplane`), ``plan`` a sequence of biplane plans
    (:func:`carmkin.biplane.plan_biplane`) or biplane joint vectors: each a run of both planes at once (an event
    per plane, each on its plane's system; the map their sum). ``skin``: the patient's
    cells already sampled (:func:`carmkin.dose.from_patient`), else sampled at ``spacing`` (m, default
    :data:`carmkin.dose.skin.DEFAULT_SPACING`)."""
    from carmkin.dose.compute import planes_dose
    from carmkin.dose.skin import DEFAULT_SPACING

    technique = Technique() if technique is None else technique
    systems, events, water, per_frame, planes = _predict(system, plan, patient, technique)
    if skin is None:
        m = planes_dose(zip(systems, events), patient, spacing=DEFAULT_SPACING if spacing is None else spacing)
    else:
        if hasattr(patient, "check_placement"):
            for s in {id(s): s for s in systems}.values():
                patient.check_placement(s, "patient")
        m = planes_dose(zip(systems, events), skin)
    return PlanDose(tuple(events), water, per_frame, m, technique, planes)
