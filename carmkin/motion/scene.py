"""What a motion planner moves and measures: the joint box, the joint speeds, the collision pairs with their exact
distances and speed bounds — for one system (its :class:`carmkin.world.World`) or a biplane (both planes' joints
in one state: each plane's world and the pairs between the planes, :class:`carmkin.world.between.Between`).

Lengths in m, angles in rad, the state's joint order that of the system (a biplane: the table's joints, then the
frontal plane's own, then the lateral plane's own, as :class:`carmkin.model.biplane.Biplane` orders them).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from carmkin.errors import MotionPlanError
from carmkin.model.biplane import Biplane
from carmkin.model.motion import Motion
from carmkin.world import World
from carmkin.world.between import Between
from carmkin.world.obstacles import link_of
from carmkin.world.swept import pair_rates

from .certificate import Certifier


@dataclass
class Scene:
    """``system`` (a system or a biplane) with its ``joint_ranges``, ``prismatic``, ``joint_names``, ``lower`` and
    ``upper`` (nq,), ``motion`` (its joints' speeds, in state order), the ``certifier`` of its pairs and
    ``pair_names`` (link, link) per pair; ``world``: the one world of a single system (None for a biplane)."""

    system: object
    joint_names: tuple[str, ...]
    joint_ranges: tuple
    prismatic: tuple[bool, ...]
    lower: np.ndarray
    upper: np.ndarray
    motion: Motion
    certifier: Certifier
    pair_names: list[tuple[str, str]]
    world: World | None = None

    @property
    def nq(self) -> int:
        return len(self.joint_names)


def _require_motion(system, what: str) -> Motion:
    if system.motion is None:
        raise MotionPlanError(f"{what} {system.name!r} has no joint speeds ([motion] in its preset): a motion cannot "
                              f"be timed")
    return system.motion


def scene_of(system, patient=None, world: World | None = None) -> Scene:
    """The scene of ``system`` (a :class:`~carmkin.model.system.CArmSystem` or a
    :class:`~carmkin.model.biplane.Biplane`) around ``patient`` (None, a patient model or a list of obstacles);
    ``world``: a built :class:`~carmkin.world.World` of the single system to reuse."""
    if isinstance(system, Biplane):
        return _biplane_scene(system, patient)
    if world is None:
        world = World(system, patient)
    elif world.system != system:  # equal systems share a world (the views' cache keys them by value)
        raise MotionPlanError("world belongs to another system: build it as carmkin.world.World(system, patient)")
    motion = _require_motion(system, "system")
    return Scene(system, system.joint_names, system.joint_ranges, system.prismatic, system.lower, system.upper, motion,
                 Certifier.for_world(world), world.link_pairs(), world)


def _biplane_scene(biplane: Biplane, patient) -> Scene:
    """Both planes in one state: the frontal world's pairs, the lateral world's, then the pairs between them."""
    frontal, lateral = World(biplane.frontal, patient), World(biplane.lateral, patient)
    between = Between(frontal, lateral)
    k, nf, nl = biplane.table_nq, biplane.frontal.nq, biplane.lateral.nq
    columns_f = np.arange(nf)                                  # frontal plane's q: the state's first nf columns
    columns_l = np.concatenate((np.arange(k), np.arange(nf, nf + nl - k)))  # lateral: the table's, then its own

    def spread(S, columns):
        out = np.zeros((len(S), biplane.nq))
        out[:, columns] = S
        return out

    ra, rb = between.rates()
    S_between = pair_rates(spread(ra, columns_f), spread(rb, columns_l))
    S = np.vstack((spread(frontal.speed_bounds, columns_f), spread(lateral.speed_bounds, columns_l), S_between))
    pf, pl = len(frontal), len(lateral)

    def distances(q):
        q_f, q_l = biplane.planes_q(q)
        return np.concatenate((frontal.distances(q=q_f), lateral.distances(q=q_l), between.distances(q_f, q_l)))

    def pair_distances(q, pairs):
        q_f, q_l = biplane.planes_q(q)
        pairs = np.asarray(pairs)
        out = np.empty(len(pairs))
        for lo, hi, measure in ((0, pf, lambda p: frontal.pair_distances(q_f, p)),
                                (pf, pf + pl, lambda p: lateral.pair_distances(q_l, p)),
                                (pf + pl, len(S), lambda p: between.pair_distances(q_f, q_l, p))):
            mine = (pairs >= lo) & (pairs < hi)
            if mine.any():
                out[mine] = measure(pairs[mine] - lo)
        return out

    motion_f = _require_motion(biplane.frontal, "the frontal plane")
    motion_l = _require_motion(biplane.lateral, "the lateral plane")
    renamed = [dataclasses.replace(j, name=n) for j, n in
               zip(tuple(motion_f.joints) + tuple(motion_l.joints[k:]), biplane.joint_names)]
    motion = Motion(tuple(renamed))
    names = ([(f"frontal {a}", f"{b}") for a, b in frontal.link_pairs()]
             + [(f"lateral {a}", f"{b}") for a, b in lateral.link_pairs()]
             + [(f"frontal {link_of(a)}", f"lateral {link_of(b)}") for a, b in between.pairs])
    return Scene(biplane, biplane.joint_names, biplane.joint_ranges, biplane.prismatic, biplane.lower, biplane.upper,
                 motion, Certifier(distances, pair_distances, S), names)
