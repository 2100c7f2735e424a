"""Joint-by-joint moves: a manual C-arm is moved one joint at a time, each move swept for collision.

From ``q_from`` to ``q_to`` the joints that differ are moved alone, in the manual order :data:`DEFAULT_ORDER`
(joints it does not name, e.g. a motorized table's, after it in q order): each time, the first pending joint
whose move alone keeps ``clearance`` along its whole path (:meth:`carmkin.world.World.swept`, certified) is
taken. When none can, the first pending one is reported blocked. Every :attr:`Move.min_distance` is the
certified lower bound of its move's swept clearance. Lengths in m, angles in rad.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from carmkin.errors import CollisionSceneError
from carmkin.validation import JOINT_VALUE_LIMIT, real_array, real_scalar

from .tolerances import DEFAULT_PATH_CLEARANCE

#: Manual move order, first to last (§4.5's guidance); joints not named come after, in q order.
DEFAULT_ORDER = ("table_translation", "vertical", "horizontal", "wigwag", "angular", "orbital")


@dataclass(frozen=True)
class Move:
    """One joint moved alone from ``start`` to ``end`` (m or rad): ``clear`` when the whole move keeps the
    clearance; ``min_distance`` the certified lower bound (m) of its swept clearance (the whole move, also
    when blocked); ``reason`` when blocked."""

    joint: str
    start: float
    end: float
    clear: bool
    min_distance: float
    reason: str | None = None


def move_order(system, order: Sequence[str] | None = None, error=CollisionSceneError) -> list[int]:
    """Joint indices in the order an operator moves them (``order``: joint names, default
    :data:`DEFAULT_ORDER`; names a system lacks are skipped only in the default)."""
    if order is None:
        named = [system.joint_names.index(n) for n in DEFAULT_ORDER if n in system.joint_names]
    else:
        if not isinstance(order, (list, tuple)) or not all(isinstance(n, str) for n in order):
            raise error(f"order must be a sequence of joint names, got {order!r}")
        unknown = [n for n in order if n not in system.joint_names]
        if unknown:
            raise error(f"order names unknown joint(s) {unknown}; joints: {', '.join(system.joint_names)}")
        named = [system.joint_names.index(n) for n in order]
    return named + [k for k in range(system.nq) if k not in named]


def joint_moves(world, q_from, q_to, order: Sequence[str] | None = None,
                clearance: float = DEFAULT_PATH_CLEARANCE) -> tuple[Move, ...]:
    """The joint-by-joint moves from ``q_from`` to ``q_to`` (nq,) in ``world`` (see the module docstring);
    the last move is the blocked one when the sequence cannot be completed."""
    system = world.system
    q_from = real_array(q_from, "q_from", (system.nq,), error=CollisionSceneError, limit=JOINT_VALUE_LIMIT,
                        unit="m, rad")
    q_to = real_array(q_to, "q_to", (system.nq,), error=CollisionSceneError, limit=JOINT_VALUE_LIMIT, unit="m, rad")
    clearance = real_scalar(clearance, "clearance", error=CollisionSceneError, low=0.0, high=1.0, unit="m")
    moves = []

    def check(q_a, q_b):
        result = world.swept(q_a, q_b, margin=clearance)
        return result.clear, result

    done, blocked = greedy_moves(q_from, q_to, move_order(system, order), check)
    for k, start, _, result in done:
        moves.append(Move(system.joint_names[k], start, float(q_to[k]), True, result.min_distance))
    if blocked is not None:
        k, start, result = blocked
        a, b = world.link_pairs()[result.contact_pair if result.contact_pair is not None else result.pair]
        moves.append(Move(system.joint_names[k], start, float(q_to[k]), False, result.min_distance,
                          f"no joint can move alone keeping {clearance * 1e3:g} mm: {system.joint_names[k]} "
                          f"brings {a} to {result.min_distance * 1e3:.1f} mm of {b}"))
    return tuple(moves)


def greedy_moves(q_from, q_to, order: list[int], check):
    """The manual rule, for any check: from ``q_from`` move, one joint at a time in ``order`` (joint indices), the
    first pending joint whose move alone ``check(q_a, q_b) -> (clear, result)`` calls clear. Returns ``(done,
    blocked)``: ``done`` the moves made, ``(joint, start, configuration after, result)`` each; ``blocked`` ``(joint,
    start, result)`` of the first pending joint when none can move, else None."""
    q, done = np.array(q_from, dtype=float), []
    pending = [k for k in order if q_from[k] != q_to[k]]
    while pending:
        for k in pending:
            target = q.copy()
            target[k] = q_to[k]
            clear, result = check(q, target)
            if clear:
                done.append((k, float(q[k]), target, result))
                q, pending = target, [j for j in pending if j != k]
                break
        else:
            k = pending[0]
            target = q.copy()
            target[k] = q_to[k]
            return done, (k, float(q[k]), check(q, target)[1])
    return done, None
