"""The collision world of a biplane: each plane's one world (its C-arm against table, floor and patient) and
the clearance between the planes (every link of one against every link of the other).

:class:`BiplaneWorld` composes two :class:`carmkin.world.World` s — built by the view planner's
:func:`carmkin.views.plan.world_for`, cached per system and patient, so a plan and its check share them —
and a :class:`carmkin.world.between.Between` over them; no coal code of its own. Distances are signed (m,
negative: penetration depth), poses in the one table frame 0.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from carmkin.errors import BiplaneError
from carmkin.model.biplane import Biplane
from carmkin.views.plan import world_for
from carmkin.world.between import Between


@dataclass(frozen=True)
class Clearance:
    """Clearances (m) of one biplane configuration: ``planes`` between the planes (``pair``: the nearest
    (frontal geometry, lateral geometry)), ``frontal`` and ``lateral`` each plane to table, floor and patient
    (``None`` for a plane whose world has no pair)."""

    planes: float
    pair: tuple[str, str]
    frontal: float | None
    lateral: float | None

    @property
    def minimum(self) -> float:
        """The smallest of the three (m)."""
        return min(v for v in (self.planes, self.frontal, self.lateral) if v is not None)


@functools.lru_cache(maxsize=8)
def _between(frontal_world, lateral_world) -> Between:
    return Between(frontal_world, lateral_world)


class BiplaneWorld:
    """The worlds of ``biplane`` (a :class:`~carmkin.model.biplane.Biplane`) with ``patient`` (as everywhere:
    None, a patient model or a list of obstacles): ``frontal`` and ``lateral`` (:class:`carmkin.world.World`)
    and ``between`` (:class:`carmkin.world.between.Between`, the frontal's geometries first)."""

    def __init__(self, biplane: Biplane, patient=None) -> None:
        if not isinstance(biplane, Biplane):
            raise BiplaneError(f"biplane must be a carmkin.model.biplane.Biplane (carmkin.biplane.load_biplane(...)), "
                               f"got {type(biplane).__name__}")
        self.biplane = biplane
        self.frontal = world_for(biplane.frontal, patient)
        self.lateral = world_for(biplane.lateral, patient)
        self.between = _between(self.frontal, self.lateral)

    def planes(self, Q) -> np.ndarray:
        """(N,) the exact smallest signed distance (m) between the planes at each biplane configuration of ``Q``
        (N, nq) (one (nq,) configuration: shape (1,))."""
        q_f, q_l = self.biplane.planes_q(np.atleast_2d(self.biplane.check(Q, "Q")))
        return self.between.clearance(q_f, q_l)

    def clearance(self, q) -> Clearance:
        """The :class:`Clearance` of one biplane configuration ``q`` (nq,)."""
        q_f, q_l = self.biplane.planes_q(self.biplane.check(q))
        d, pair = self.between.nearest(q_f, q_l)
        own = [float(w.clearance(v)[0]) if len(w) else None for w, v in ((self.frontal, q_f), (self.lateral, q_l))]
        return Clearance(float(d[0]), self.between.pairs[int(pair[0])], *own)


def check_rest(biplane: Biplane) -> float:
    """The planes' clearance at rest (m); :class:`~carmkin.errors.BiplaneError` naming the fields to change if
    they intersect there (a negative signed distance)."""
    world = BiplaneWorld(biplane)
    rest = world.clearance(np.array(biplane.rest))
    if rest.planes < 0.0:
        a, b = rest.pair
        raise BiplaneError(
            f"Biplane.rest: the planes intersect at rest ({biplane.name}): frontal {a} and lateral {b} overlap by "
            f"{-rest.planes * 1e3:.1f} mm; change the rest configuration (Biplane.rest, a preset's [rest.*]) or the "
            "lateral plane's placement (Biplane.lateral.setup, a preset's [lateral.setup])")
    return rest.planes


def load_biplane(name_or_path) -> Biplane:
    """A biplane preset (built-in name, e.g. ``"angio-biplane"``, or a ``.toml`` path) as a
    :class:`~carmkin.model.biplane.Biplane` (:func:`carmkin.presets.read_biplane`), its planes checked clear of
    each other at rest (:func:`check_rest`)."""
    from carmkin.presets import read_biplane

    biplane = read_biplane(name_or_path)
    try:
        check_rest(biplane)
    except BiplaneError as exc:
        raise BiplaneError(f"{name_or_path}: {exc}") from None
    return biplane
