"""Kinematic singularities of the 6-DOF C-arm + table chain (§4.3.2, eq. 4.7).

Convention of the manipulator Jacobian (:func:`jacobian`): Pinocchio's frame Jacobian of ``xray_source``
in ``LOCAL_WORLD_ALIGNED``, i.e. the twist of the source expressed **at the source centre, along the
table-frame axes**, rows **linear first** ``[v; ω]`` (m/s, rad/s), columns in the order of q (m/s and
rad/s of the joints). In this convention Pinocchio's ``det J`` equals eq. 4.7 *sign included*:

    det J = (sγ3 cθ2 + cγ3 sθ2) · sγ1 · cθ4 = sin(θ2 + γ3) · sin γ1 · cos θ4

for any geometry (a1, a2, l1, l2) and table setup (γ2, D1..D3 drop out). Why: with the prismatic columns
(d0, d1, d3) moved first the matrix is block triangular, ``det J = det[z0 z1 z3] · det[z2 z4 z5]`` (one
column swap, sign −1), and the two 3×3 determinants are ``−sin(θ2 + γ3) sin γ1`` and ``cos θ4``.
The value does not depend on the point or the axes the twist is expressed in (``LOCAL``, ``WORLD`` and
``LOCAL_WORLD_ALIGNED`` differ by an adjoint map of determinant 1); it changes sign if the rows are put
angular first (three row swaps). It is dimensionless, since the linear rows of the revolute columns
(the only entries in m) do not enter the block-triangular product.

Measures (:func:`measures`) use the *scaled* Jacobian ``Js = diag(I3/L, I3) · J · diag(L for prismatic,
1 for revolute)`` with a characteristic length L (default: the orbital offset l2, the lever arm from the
source to the angular axis): linear velocities in units of L/s and prismatic rates in L/s, so every entry
is dimensionless and singular values of mixed joints compare. ``det Js = det J`` (three factors L cancel
three 1/L), so |det J| and the Yoshikawa manipulability ``sqrt(det(Js Jsᵀ)) = |det Js|`` are scale-free;
the smallest singular value and the condition number depend on L.

The three singular sets (:class:`~carmkin.model.singular_cases.SingularCase`, valued by the paper's letters;
eq. 4.7 and the case vocabulary live in :mod:`carmkin.model.singular_cases`):

- ``"a"``: sin γ1 = 0, table axis Z0 ∥ vertical axis Z1 (a property of the setup, not of q);
- ``"b"``: cos θ4 = 0, orbital axis Z5 ∥ wigwag axis Z2;
- ``"c"``: sin(θ2 + γ3) = 0, i.e. θ2 ≡ −γ3 (mod π): the horizontal axis Z3 is parallel to the horizontal
  projection of the table axis (the three prismatic axes are coplanar); for a level table (γ1 = ±90°)
  this is the paper's "table translation ∥ horizontal movement".

Each factor is the sine of an angle, so :func:`singularity_distances` reports ``asin|factor|`` (rad): the
change of γ1, θ4 or θ2 that reaches the set.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from carmkin.errors import (
    SingularityError,  # noqa: F401 (defined there, raised here)
)
from carmkin.model import singular_cases
from carmkin.model.kinematics import check_configuration
from carmkin.model.params import JOINT_NAMES
from carmkin.model.singular_cases import SingularCase, SingularFactors
from carmkin.model.system import CArmSystem
from carmkin.transforms import wrap_angle
from carmkin.validation import MAX_DISTANCE, MIN_DISTANCE, distance, instance, integer, real_scalar
from carmkin.validation import joint_index as _joint_index

#: Frame whose Jacobian is analysed, and the Pinocchio reference frame (twist at its origin, table axes).
FRAME = "xray_source"
REFERENCE_FRAME = pin.LOCAL_WORLD_ALIGNED
#: The three singular sets of §4.3.2 (:class:`~carmkin.model.singular_cases.SingularCase`, values "a", "b", "c").
CASES = singular_cases.CASES
#: The geometric condition of each case, in words.
CASE_TITLES = {case: case.title for case in CASES}
#: What is lost in each case, in words (directions named in the table frame; n is the reported axis).
CASE_LOSSES = {case: case.loss for case in CASES}


def _check_system(system) -> CArmSystem:
    return instance(system, CArmSystem, "system", error=SingularityError, hint="carmkin.load_preset(...)")


def _paper_chain(system: CArmSystem, q) -> np.ndarray:
    if _check_system(system).nq != 6:
        raise SingularityError(
            f"eq. 4.7 and the three singular cases hold for the paper's 6-joint chain; system {system.name!r} "
            f"has {system.nq} joints ({', '.join(system.joint_names)})")
    return check_configuration(q, 6)


# --- closed form (eq. 4.7), vectorized --------------------------------------------------------------------
def singular_factors(system: CArmSystem, q) -> SingularFactors:
    """Factors (sin γ1, cos θ4, sin(θ2 + γ3)) of eq. 4.7 for q (6,) or (N, 6): floats or (N,) arrays."""
    q = _paper_chain(system, q)
    return singular_cases.factors(system.setup, q[..., 2], q[..., 4])


def det_closed_form(system: CArmSystem, q) -> np.ndarray:
    """``det J`` by eq. 4.7 (dimensionless) for q (6,) or (N, 6), in the convention of :func:`jacobian`."""
    q = _paper_chain(system, q)
    return singular_cases.det_closed_form(system.setup, q[..., 2], q[..., 4])


def singularity_distances(system: CArmSystem, q) -> dict[SingularCase, np.ndarray]:
    """Distance to each singular set (rad): ``asin|factor|``, i.e. how far γ1, θ4 or θ2 is from the set.

    Keys are :data:`CASES`; values are floats for q (6,) and (N,) arrays for q (N, 6).
    """
    return singular_cases.distances(singular_factors(system, q))


# --- Pinocchio ---------------------------------------------------------------------------------------------
def _check_reference_frame(reference_frame) -> None:
    if not isinstance(reference_frame, pin.ReferenceFrame):
        raise SingularityError(f"reference_frame must be a pinocchio.ReferenceFrame (e.g. pin.LOCAL_WORLD_ALIGNED), "
                               f"got {reference_frame!r:.60}")


def jacobian(system: CArmSystem, q, reference_frame=REFERENCE_FRAME) -> np.ndarray:
    """Pinocchio's Jacobian (6, nq) of ``xray_source``: rows ``[v; ω]`` (m/s, rad/s), see module docstring."""
    q = check_configuration(q, _check_system(system).nq)
    if q.ndim != 1:
        raise SingularityError(f"jacobian takes one configuration (nq,), got shape {q.shape}; use jacobians")
    _check_reference_frame(reference_frame)
    model = system.pinocchio()[0]
    data = model.createData()
    return pin.computeFrameJacobian(model, data, q, model.getFrameId(FRAME), reference_frame).copy()


def jacobians(system: CArmSystem, q, reference_frame=REFERENCE_FRAME) -> np.ndarray:
    """Jacobians (N, 6, nq) for configurations (N, nq) (one Pinocchio call per configuration)."""
    q = np.atleast_2d(check_configuration(q, _check_system(system).nq))
    _check_reference_frame(reference_frame)
    model = system.pinocchio()[0]
    data = model.createData()
    frame_id = model.getFrameId(FRAME)
    out = np.empty((len(q), 6, model.nv))
    for k, qk in enumerate(q):
        out[k] = pin.computeFrameJacobian(model, data, qk, frame_id, reference_frame)
    return out


def det_jacobian(system: CArmSystem, q) -> np.ndarray:
    """``det J`` of Pinocchio's Jacobian for q (6,) or (N, 6) (dimensionless)."""
    q = _paper_chain(system, q)
    return np.linalg.det(jacobians(system, np.atleast_2d(q))).reshape(q.shape[:-1])


# --- scale-aware measures -----------------------------------------------------------------------------------
def characteristic_length(system: CArmSystem) -> float:
    """Default characteristic length L (m): the orbital offset l2, source-to-angular-axis lever arm."""
    return _check_system(system).carm.orbital_offset


#: Bounds (m) of a characteristic length: the physical distances of :mod:`carmkin.validation` (1 µm … 10 m),
#: so that ``1/L`` and ``L`` scale a Jacobian without overflow or a NaN measure.
MIN_LENGTH, MAX_LENGTH = MIN_DISTANCE, MAX_DISTANCE


def _check_length(system: CArmSystem, length: float | None) -> float:
    if length is None:
        return characteristic_length(system)
    return distance(length, "characteristic length", error=SingularityError, low=MIN_LENGTH, high=MAX_LENGTH)


def scaling(system: CArmSystem, length: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(S, D)`` with ``Js = diag(S) · J · diag(D)``: S = (1/L)×3 then 1×3, D = L for prismatic joints."""
    L = _check_length(_check_system(system), length)
    S = np.array([1.0 / L] * 3 + [1.0] * 3)
    D = np.where(np.array(system.prismatic), L, 1.0)
    return S, D


def scaled_jacobian(system: CArmSystem, q, length: float | None = None) -> np.ndarray:
    """Dimensionless Jacobian ``Js`` (6, nq) (see the module docstring); ``det Js = det J``."""
    S, D = scaling(system, length)
    return S[:, None] * jacobian(system, q) * D[None, :]


@dataclass(frozen=True)
class Measures:
    """Scale-aware closeness-to-singularity measures of one configuration (all dimensionless).

    Attributes:
        det: signed det J (nan if the Jacobian is not square). abs_det: |det J|.
        singular_values: of the scaled Jacobian Js, descending.
        sigma_min: smallest singular value of Js. condition: σmax/σmin (inf at a singularity).
        manipulability: Yoshikawa's ``sqrt(det(Js Jsᵀ))`` (= |det J| for the square 6-DOF chain).
        length: characteristic length L used for the scaling (m).
    """

    det: float
    abs_det: float
    singular_values: np.ndarray
    sigma_min: float
    condition: float
    manipulability: float
    length: float


def measures(system: CArmSystem, q, length: float | None = None) -> Measures:
    """:class:`Measures` of configuration q (nq,) from Pinocchio's Jacobian, scaled by length L (m)."""
    L = _check_length(system, length)
    S, D = scaling(system, L)
    J = jacobian(system, q)
    return _measures(J, S[:, None] * J * D[None, :], L)


def _measures(J: np.ndarray, Js: np.ndarray, length: float) -> Measures:
    sv = np.linalg.svd(Js, compute_uv=False)
    det = float(np.linalg.det(J)) if J.shape == (6, 6) else float("nan")
    condition = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    return Measures(det, abs(det), sv, float(sv[-1]), condition, float(np.prod(sv)), length)


# --- classification -----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CaseReport:
    """One singular set: its factor (eq. 4.7), distance (rad), membership, the lost axis n (table frame)."""

    case: SingularCase
    title: str
    factor: float
    distance: float
    singular: bool
    near: bool
    axis: np.ndarray
    loss: str


@dataclass(frozen=True)
class Classification:
    """Which singular sets q is in or near, with the measures and the numerically lost directions.

    Attributes:
        cases: :class:`CaseReport` per case of :data:`CASES`.
        rank: numerical rank of the scaled Jacobian (singular values above ``rtol · σmax``).
        measures: :class:`Measures` at q.
        joint_null: joint velocity (m/s, rad/s; unit norm in scaled units) closest to moving the source
            not at all: right singular vector of Js for σmin, mapped back to SI.
        twist_constraint: u (6,) = left singular vector for σmin, mapped to SI: at a singularity every
            twist ``[v; ω]`` the source can make satisfies ``u · [v; ω] = 0``.
    """

    q: np.ndarray
    cases: dict[SingularCase, CaseReport]
    rank: int
    measures: Measures
    joint_null: np.ndarray
    twist_constraint: np.ndarray = field(repr=False)

    @property
    def singular_cases(self) -> tuple[str, ...]:
        """Letters of the sets q lies in (within the tolerance)."""
        return tuple(c for c, r in self.cases.items() if r.singular)

    @property
    def near_cases(self) -> tuple[str, ...]:
        """Letters of the sets q lies within ``near`` of (including those it lies in)."""
        return tuple(c for c, r in self.cases.items() if r.near)

    def describe(self) -> str:
        """Multi-line text: per case distance (deg) and status, the rank, the measures and lost directions."""
        lines = []
        for c, r in self.cases.items():
            status = "SINGULAR" if r.singular else ("near" if r.near else "clear")
            lines.append(f"({c}) {r.title}: factor {r.factor:+.6f}, distance {math.degrees(r.distance):.4f} deg "
                         f"[{status}]")
            if r.near:
                lines.append(f"    lost: {r.loss}; n = {np.array2string(r.axis, precision=4, suppress_small=True)}")
        m = self.measures
        lines.append(f"rank {self.rank}; det J {m.det:+.6g}; sigma_min {m.sigma_min:.6g}; condition "
                     f"{m.condition:.6g}; manipulability {m.manipulability:.6g} (L = {m.length * 1e3:.1f} mm)")
        kind = "null" if self.rank < len(self.joint_null) else "weakest (closest to null)"
        lines.append(f"{kind} joint direction (m/s, rad/s): " + ", ".join(
            f"{n}={v:+.4f}" for n, v in zip(JOINT_NAMES, self.joint_null)))
        lines.append("twist constraint u on [v; ω]: " + np.array2string(self.twist_constraint, precision=4,
                                                                        suppress_small=True))
        return "\n".join(lines)


def joint_axes(system: CArmSystem, q) -> np.ndarray:
    """Unit directions z0..z5 (6, 3) of the joint axes in the table frame, from the DH frames at q (6,)."""
    q = _paper_chain(system, q)
    frames = system.dh_frames(q)
    return np.vstack(([0.0, 0.0, 1.0], frames[:5, :3, 2]))


def lost_axes(system: CArmSystem, q) -> dict[SingularCase, np.ndarray]:
    """The axis n of each case's loss (table frame, unit; see :data:`CASE_LOSSES`): Z1×Z3, Z2×Z4, Z0×Z1.

    For case (a) the axis n of a translation, (b) of a rotation, (c) of a translation. Where the cross
    product vanishes (e.g. Z0 ∥ Z1 for case c at γ1 = 0) the zero vector is returned.
    """
    z = joint_axes(system, q)
    pairs = dict(zip(CASES, ((1, 3), (2, 4), (0, 1))))
    out = {}
    for case, (i, j) in pairs.items():
        n = np.cross(z[i], z[j])
        norm = np.linalg.norm(n)
        out[case] = n / norm if norm > 1e-12 else np.zeros(3)
    return out


def classify(system: CArmSystem, q, near: float = math.radians(5.0), tol: float = 1e-9,
             length: float | None = None, rtol: float = 1e-9) -> Classification:
    """Classify q (6,) against the three singular sets of §4.3.2.

    Args:
        near: a set within this distance (rad, see :func:`singularity_distances`) counts as near.
        tol: a set within this distance (rad) counts as reached (singular).
        length: characteristic length L (m) for the measures; default :func:`characteristic_length`.
        rtol: singular values below ``rtol · σmax`` of the scaled Jacobian count as zero for the rank.
    """
    q = _paper_chain(system, q)
    if q.ndim != 1:
        raise SingularityError(f"classify takes one configuration (6,), got shape {q.shape}")
    near = real_scalar(near, "near", error=SingularityError, low=0.0, high=math.pi, unit="rad")
    tol = real_scalar(tol, "tol", error=SingularityError, low=0.0, high=math.pi, unit="rad")
    rtol = real_scalar(rtol, "rtol", error=SingularityError, low=0.0, high=1.0)
    if not (0.0 <= tol <= near):
        raise SingularityError(f"need 0 <= tol <= near (rad), got tol={tol}, near={near}")
    factors = singular_factors(system, q)
    distances = singularity_distances(system, q)
    axes = lost_axes(system, q)
    cases = {
        c: CaseReport(c, c.title, float(f), float(distances[c]), bool(distances[c] <= tol),
                      bool(distances[c] <= near), axes[c], c.loss)
        for c, f in zip(CASES, factors)
    }
    L = _check_length(system, length)
    S, D = scaling(system, L)
    J = jacobian(system, q)
    Js = S[:, None] * J * D[None, :]
    m = _measures(J, Js, L)
    U, sv, Vt = np.linalg.svd(Js)
    rank = int(np.sum(sv > rtol * sv[0]))
    joint_null = D * Vt[-1]
    twist = S * U[:, -1]
    return Classification(q.copy(), cases, rank, m, _signed_unit(joint_null), _signed_unit(twist))


def _signed_unit(v: np.ndarray) -> np.ndarray:
    """``v`` normalized, with its largest-magnitude entry positive (a reproducible sign)."""
    v = v / np.linalg.norm(v)
    return v if v[np.argmax(np.abs(v))] >= 0 else -v


# --- checks -----------------------------------------------------------------------------------------------
def check_determinant(system: CArmSystem, samples: int, random_setups: int = 0, seed: int = 0) -> float:
    """Largest |det J (Pinocchio) − eq. 4.7| over random configurations (and random non-isocentric systems)."""
    from carmkin.model.sampling import random_configurations, random_system

    samples = integer(samples, "samples", low=0, high=10_000_000, error=SingularityError)
    random_setups = integer(random_setups, "random_setups", low=0, high=100_000, error=SingularityError)
    rng = np.random.default_rng(integer(seed, "seed", low=0, error=SingularityError))
    systems = [_check_system(system)] + [random_system(rng, system) for _ in range(random_setups)]
    worst = 0.0
    for k, sys_k in enumerate(systems):
        n = samples // len(systems) + (k < samples % len(systems))
        if n:
            q = random_configurations(rng, sys_k, n)
            worst = max(worst, float(np.abs(det_jacobian(sys_k, q) - det_closed_form(sys_k, q)).max()))
    return worst


# --- maps ---------------------------------------------------------------------------------------------------
#: Measures a map can show, computed on a grid.
MAP_MEASURES = ("det", "manipulability", "inverse-condition", "sigma-min")


#: The paper's symbols of the six joints every system has (§4.3.1), accepted wherever a joint name is.
SYMBOLS = dict(zip(("d0", "d1", "theta2", "d3", "theta4", "theta5"), JOINT_NAMES))
#: Most grid points per map axis (a 1001 x 1001 map): bounds the cost of a call.
MAX_GRID = 1001


def joint_index(joint, system: CArmSystem | None = None) -> int:
    """Index in q of ``system``'s joint (default: the paper's 6-joint chain) given by name (``"angular"``),
    symbol (``"theta4"``) or index ``0 <= i < nq`` (:func:`carmkin.validation.joint_index`: no negative
    alias, no bool, no float); else :class:`SingularityError` naming the valid names and range."""
    names = JOINT_NAMES if system is None else _check_system(system).joint_names
    if isinstance(joint, str):
        key = joint.strip().lower()
        joint = SYMBOLS.get(key, key) if key in SYMBOLS or key in names else joint
    return _joint_index(joint, "joint", len(names), names=names, error=SingularityError)


def _pair(system: CArmSystem, pair) -> tuple[int, int]:
    if isinstance(pair, (str, bytes)) or np.ndim(pair) != 1 or len(pair) != 2:
        raise SingularityError(f"pair must be two joints (names or indices), got {pair!r:.80}")
    try:
        i, j = joint_index(pair[0], system), joint_index(pair[1], system)
    except SingularityError as exc:
        raise SingularityError(f"pair: {exc}") from None
    if i == j:
        raise SingularityError(f"a map needs two different joints, got {system.joint_names[i]} twice")
    return i, j


def grid_axis(system: CArmSystem, joint, n: int) -> np.ndarray:
    """``n`` grid values of a joint (name or index, :func:`joint_index`): revolute over a full turn [−π, π],
    prismatic over its range (m or rad)."""
    joint = joint_index(joint, _check_system(system))
    n = integer(n, "n (grid points per axis)", low=2, high=MAX_GRID, error=SingularityError)
    if system.prismatic[joint]:
        r = system.joint_ranges[joint]
        return np.linspace(r.lower, r.upper, n)
    return np.linspace(-math.pi, math.pi, n)


def _paper_columns(system: CArmSystem) -> list[int]:
    """Indices in q of the paper's six joints (table translation and the five C-arm joints)."""
    return [system.joint_names.index(name) for name in JOINT_NAMES]


def measure_map(system: CArmSystem, q, pair: tuple[int, int], n: int = 61, measure: str = "det",
                length: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(x, y, values)`` of a measure over two joints (others at q): values has shape (len(y), len(x)).

    Any system: ``pair`` names two joints by name, symbol or index (:func:`joint_index`), q has shape (nq,).
    ``"det"`` is |det| of the Jacobian's columns of the paper's six joints (the extra table joints held):
    on the 6-joint chain eq. 4.7 in closed form, vectorized; with a motorized table Pinocchio per grid point.
    The other measures (of the scaled 6 x nq Jacobian) call Pinocchio per grid point (fine up to ~100×100).
    """
    q = check_configuration(q, _check_system(system).nq)
    if q.ndim != 1:
        raise SingularityError(f"measure_map takes one configuration ({system.nq},), got shape {q.shape}")
    if not isinstance(measure, str) or measure not in MAP_MEASURES:
        raise SingularityError(f"unknown measure {measure!r}: use one of {', '.join(MAP_MEASURES)}")
    length = _check_length(system, length)  # checked whatever the measure (the determinant does not read it)
    i, j = _pair(system, pair)
    x, y = grid_axis(system, i, n), grid_axis(system, j, n)
    grid = np.broadcast_to(q, (len(y), len(x), system.nq)).copy()
    grid[..., i] = x[None, :]
    grid[..., j] = y[:, None]
    flat = grid.reshape(-1, system.nq)
    if measure == "det" and system.nq == 6:
        values = np.abs(det_closed_form(system, flat))
    elif measure == "det":
        values = np.abs(np.linalg.det(jacobians(system, flat)[:, :, _paper_columns(system)]))
    else:
        S, D = scaling(system, length)
        sv = np.linalg.svd(S[:, None] * jacobians(system, flat) * D[None, :], compute_uv=False)
        values = {"manipulability": lambda s: s.prod(axis=-1), "sigma-min": lambda s: s[:, -1],
                  "inverse-condition": lambda s: s[:, -1] / s[:, 0]}[measure](sv)
    return x, y, values.reshape(len(y), len(x))


def singular_curves(system: CArmSystem, pair, q=None) -> list[tuple[str, int, float]]:
    """The C-arm's singular sets that are lines in a map over ``pair`` (two joints by name, symbol or index,
    any system): ``(case, joint index in q, value)``, values wrapped to (−π, π].

    Case b at the ``angular`` joint, θ4 = ±π/2. Case c at the ``wigwag`` joint, where the table axis Z0, the
    vertical axis Z1 and the horizontal axis Z3 are coplanar: θ2 = −γ3 + kπ on the 6-joint chain; with a
    motorized table the table top's joints turn Z0, so the wigwag values are solved from the DH frames at
    ``q`` (nq,) (default: every joint at 0): ``(Z0 × Z1) · Z3(θ2) = 0`` with Z3 turning about Z2.
    """
    i, j = _pair(_check_system(system), pair)
    q = np.zeros(system.nq) if q is None else check_configuration(q, system.nq)
    if q.ndim != 1:
        raise SingularityError(f"singular_curves takes one configuration ({system.nq},), got shape {q.shape}")
    out = []
    names = system.joint_names
    angular, wigwag = names.index("angular"), names.index("wigwag")
    if angular in (i, j):
        out += [(SingularCase.ORBITAL_PARALLEL_TO_WIGWAG, angular, wrap_angle(v)) for v in (-math.pi / 2, math.pi / 2)]
    if wigwag in (i, j):
        out += [(SingularCase.TABLE_PARALLEL_TO_HORIZONTAL, wigwag, v) for v in _case_c_wigwag(system, q, wigwag)]
    return out


def _case_c_wigwag(system: CArmSystem, q: np.ndarray, wigwag: int) -> list[float]:
    """Wigwag values (rad, wrapped) with ``(Z0 × Z1) · Z3 = 0``: ``Z3(φ) = Rodrigues(Z2, φ) Z3(q)`` gives
    ``A cos φ + B sin φ + C = 0``; on the 6-joint chain this is θ2 = −γ3 + kπ (tested against it)."""
    frames = system.dh_frames(q)
    z1, z2, z3 = frames[0, :3, 2], frames[1, :3, 2], frames[2, :3, 2]
    n = np.cross((0.0, 0.0, 1.0), z1)
    c = float((n @ z2) * (z2 @ z3))
    a, b = float(n @ z3) - c, float(n @ np.cross(z2, z3))
    radius = math.hypot(a, b)
    if radius == 0.0 or abs(c) > radius:
        return []
    base, spread = math.atan2(b, a), math.acos(max(-1.0, min(1.0, -c / radius)))
    return sorted({wrap_angle(float(q[wigwag]) + base + s) for s in (spread, -spread)})
