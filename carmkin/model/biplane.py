"""`Biplane`: two C-arm planes (frontal and lateral) sharing one table and one isocentre, as a value.

Each plane is a :class:`~carmkin.model.system.CArmSystem` in the one table frame 0: the frontal plane's and
the lateral plane's table (:class:`~carmkin.model.params.TableGeometry`, its translation and motorized joints)
are one and the same table, so the two systems must hold equal tables. Every one-plane tool works on either
plane unchanged; this module only ties their joint vectors together.

**The joint vector of a biplane** (``nq = k + n_f + n_l`` for a table of ``k`` joints)::

    q = [table joints (k: table translation d0, then a motorized table's joints, as in each plane),
         frontal C-arm joints (n_f, the frontal system's joints after its table's: vertical, wigwag,
                               horizontal, angular, orbital for the five-joint chain),
         lateral C-arm joints (n_l, the same for the lateral system)]

:meth:`Biplane.planes_q` splits it into each plane's own vector ``[table joints, that plane's C-arm joints]``
(the lateral plane's table joints are the frontal's: the table is one) and :meth:`Biplane.join` puts two
plane vectors back together. Lengths in m, angles in rad, poses in the table frame 0.

The checks here need no collision model (numpy only): equal tables, a rest configuration within the ranges,
and one isocentre (the two beams' points at each plane's source–isocentre distance, ``orbital_offset``,
within :data:`ISOCENTRE_TOLERANCE` at rest). That the planes do not intersect at rest needs the collision
world: :func:`carmkin.biplane.check_rest` (run by :func:`carmkin.biplane.load_biplane`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from carmkin.errors import BiplaneError
from carmkin.validation import JOINT_VALUE_LIMIT, real_array

from .params import JOINT_RANGE_TOLERANCE
from .system import CArmSystem

#: The two planes' isocentres (each beam's point at its source–isocentre distance) coincide at rest to this (m).
ISOCENTRE_TOLERANCE = 1e-3
#: The planes, in the order of a biplane's joint vector and of its poses.
PLANES = ("frontal", "lateral")

def table_joint_count(system: CArmSystem) -> int:
    """Joints of a system's table (its translation d0 and a motorized table's joints): the first of its q."""
    return 1 + len(system.table.joints)


def default_rest(system: CArmSystem) -> np.ndarray:
    """A plane's default rest configuration (nq,): each joint at 0 where 0 is in its range, else mid-range."""
    lower, upper = system.lower, system.upper
    return np.where((lower <= 0.0) & (upper >= 0.0), 0.0, 0.5 * (lower + upper))


@dataclass(frozen=True)
class Biplane:
    """A frontal and a lateral plane on one table. ``rest``: the biplane configuration (nq,) the planes park
    in (m, rad; ``None``: :func:`default_rest` of each plane); ``name`` for people."""

    frontal: CArmSystem
    lateral: CArmSystem
    rest: tuple | None = None
    name: str = "biplane"

    def __post_init__(self) -> None:
        for field in PLANES:
            value = getattr(self, field)
            if not isinstance(value, CArmSystem):
                raise BiplaneError(f"Biplane.{field} must be a carmkin.CArmSystem (carmkin.load_preset(...)), got "
                                   f"{type(value).__name__}")
        if not isinstance(self.name, str):
            raise BiplaneError(f"Biplane.name must be a string, got {self.name!r:.60}")
        if self.lateral.table != self.frontal.table:
            differs = [f.name for f in dataclasses.fields(self.frontal.table)
                       if getattr(self.frontal.table, f.name) != getattr(self.lateral.table, f.name)]
            raise BiplaneError(f"Biplane.lateral.table must be Biplane.frontal.table (the planes share one table), "
                               f"but its {', '.join(differs)} differ: give the lateral plane the frontal's table "
                               "(lateral.replace(table=frontal.table))")
        if self.rest is None:
            rest = self.join(default_rest(self.frontal), default_rest(self.lateral))
        else:
            rest = real_array(self.rest, "Biplane.rest", (self.nq,), error=BiplaneError, limit=JOINT_VALUE_LIMIT,
                              unit="m, rad")
        for r, v, name in zip(self.joint_ranges, rest.tolist(), self.joint_names):
            if not r.contains(v):
                raise BiplaneError(f"Biplane.rest: {name} = {v:g} is outside its range [{r.lower:g}, {r.upper:g}] "
                                   "(m or rad)")
        object.__setattr__(self, "rest", tuple(rest.tolist()))
        iso = self.isocentres(rest)
        gap = float(np.linalg.norm(iso[0] - iso[1]))
        if gap > ISOCENTRE_TOLERANCE:
            raise BiplaneError(
                f"Biplane.lateral.setup: the planes must share one isocentre, but at rest the frontal's is at "
                f"{np.round(iso[0] * 1e3, 1).tolist()} mm and the lateral's at {np.round(iso[1] * 1e3, 1).tolist()} "
                f"mm (table frame), {gap * 1e3:.1f} mm apart (at most {ISOCENTRE_TOLERANCE * 1e3:g} mm)")

    # --- joints ---------------------------------------------------------------------------------------
    @property
    def table_nq(self) -> int:
        """Number of table joints, shared by the planes (1 + a motorized table's joints)."""
        return table_joint_count(self.frontal)

    @property
    def nq(self) -> int:
        """Number of biplane joints: the table's, then each plane's own (five each for the five-joint chain)."""
        return self.frontal.nq + self.lateral.nq - self.table_nq

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The table joints' names, then ``frontal.<joint>`` and ``lateral.<joint>`` in the order of q."""
        k = self.table_nq
        return (self.frontal.joint_names[:k] + tuple(f"frontal.{n}" for n in self.frontal.joint_names[k:])
                + tuple(f"lateral.{n}" for n in self.lateral.joint_names[k:]))

    @property
    def joint_ranges(self) -> tuple:
        """Ranges (m or rad) in the order of q."""
        return self.frontal.joint_ranges + self.lateral.joint_ranges[self.table_nq:]

    @property
    def prismatic(self) -> tuple[bool, ...]:
        return self.frontal.prismatic + self.lateral.prismatic[self.table_nq:]

    @property
    def lower(self) -> np.ndarray:
        return np.concatenate((self.frontal.lower, self.lateral.lower[self.table_nq:]))

    @property
    def upper(self) -> np.ndarray:
        return np.concatenate((self.frontal.upper, self.lateral.upper[self.table_nq:]))

    def check(self, q, name: str = "q") -> np.ndarray:
        """``q`` (nq,) or (N, nq) as a finite float array, or :class:`BiplaneError` naming ``name``."""
        try:
            batch = np.ndim(q) > 1
        except ValueError:  # ragged nesting: real_array names it
            batch = False
        shape = (None, self.nq) if batch else (self.nq,)
        return real_array(q, name, shape, error=BiplaneError, limit=JOINT_VALUE_LIMIT, unit="m, rad")

    def planes_q(self, q) -> tuple[np.ndarray, np.ndarray]:
        """``(q_frontal, q_lateral)``: each plane's own joint vector (its nq,) or (N, its nq) from a biplane q."""
        q = self.check(q)
        k, n = self.table_nq, self.frontal.nq
        return q[..., :n].copy(), np.concatenate((q[..., :k], q[..., n:]), axis=-1)

    def join(self, q_frontal, q_lateral) -> np.ndarray:
        """The biplane q from each plane's joint vector; their table joints must agree (to
        :data:`~carmkin.model.params.JOINT_RANGE_TOLERANCE`): the table is one."""
        k = self.table_nq
        f = real_array(q_frontal, "q_frontal", None, error=BiplaneError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
        lat = real_array(q_lateral, "q_lateral", None, error=BiplaneError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
        for value, name, system in ((f, "q_frontal", self.frontal), (lat, "q_lateral", self.lateral)):
            if value.ndim not in (1, 2) or value.shape[-1] != system.nq:
                raise BiplaneError(f"{name} must be ({system.nq},) or (N, {system.nq}) joint values (m, rad), got "
                                   f"shape {value.shape}")
        if f.shape[:-1] != lat.shape[:-1]:
            raise BiplaneError(f"q_frontal and q_lateral must hold as many configurations, got {f.shape} and {lat.shape}")
        gap = np.abs(f[..., :k] - lat[..., :k])
        if np.any(gap > JOINT_RANGE_TOLERANCE):
            j = int(np.argwhere(gap > JOINT_RANGE_TOLERANCE)[0][-1])
            raise BiplaneError(f"q_lateral's {self.frontal.joint_names[j]} differs from q_frontal's by "
                               f"{float(gap.max()):g} (m or rad): the planes share one table")
        return np.concatenate((f, lat[..., k:]), axis=-1)

    # --- kinematics -----------------------------------------------------------------------------------
    def fk(self, q) -> np.ndarray:
        """Poses of both planes' ``xray_source`` in the table frame: (2, 4, 4) for q (nq,), (N, 2, 4, 4) for
        (N, nq); index 0 the frontal plane, 1 the lateral."""
        q_f, q_l = self.planes_q(q)
        return np.stack((self.frontal.fk(q_f), self.lateral.fk(q_l)), axis=-3)

    def isocentres(self, q) -> np.ndarray:
        """Each plane's isocentre (2, 3) or (N, 2, 3) in the table frame (m): its beam's point at its
        source–isocentre distance (``carm.orbital_offset``)."""
        T = self.fk(q)
        sod = np.array([self.frontal.carm.orbital_offset, self.lateral.carm.orbital_offset])
        return T[..., :3, 3] + sod[:, None] * T[..., :3, 2]
