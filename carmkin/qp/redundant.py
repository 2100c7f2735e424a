"""Redundant chains (multi-DOF tables, issue 9): joint weights of the minimal motion, locked joints, seeds.

Among the infinitely many solutions of a chain with more joints than task rows, the QP moves little in the
weighted norm ``sqrt(dq^T diag(w) dq)`` (m and rad weighted alike: 1 m ~ 1 rad); locked joints stay at their
seed value.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .options import QPIKError

#: Weight ratio of :func:`joint_weights` ``prefer``: the non-preferred group's joints cost this much more.
PREFERENCE_RATIO = 100.0


@dataclass(frozen=True)
class Redundancy:
    """How a redundant chain spends its extra joints: ``weights`` (:func:`joint_weights`: ``None``, (nq,) or a
    dict by joint name), ``prefer`` (``"table"``, ``"carm"`` or ``None``), ``free`` (names of the joints that
    may move; ``None``: all). Checked against a system when a solver is prepared."""

    weights: object = None
    prefer: str | None = None
    free: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if self.prefer is not None and (not isinstance(self.prefer, str) or self.prefer not in ("table", "carm")):
            raise QPIKError(f"prefer must be 'table', 'carm' or None, got {self.prefer!r}")
        if self.free is not None:
            if (isinstance(self.free, (str, bytes, dict)) or not hasattr(self.free, "__iter__")
                    or not all(isinstance(n, str) for n in self.free)):
                raise QPIKError(f"free must be a sequence of joint names, got {self.free!r}")
            object.__setattr__(self, "free", tuple(self.free))
        if self.weights is not None and not isinstance(self.weights, dict):
            if isinstance(self.weights, (str, bytes)):
                raise QPIKError(f"joint_weights must be numbers or a dict by joint name, got {self.weights!r}")
            try:  # a tuple, so that the options hash; the values are checked by check_weights
                object.__setattr__(self, "weights", tuple(np.ravel(np.asarray(self.weights, dtype=object)).tolist()))
            except (TypeError, ValueError):
                raise QPIKError(f"joint_weights must be numbers or a dict by joint name, got {self.weights!r}") from None

    def __hash__(self) -> int:
        weights = tuple(sorted(self.weights.items())) if isinstance(self.weights, dict) else self.weights
        return hash((weights, self.prefer, self.free))


def check_weights(weights, nv: int) -> np.ndarray:
    """``weights`` as a float array (nv,) of finite positive numbers, else :class:`QPIKError`."""
    try:
        w = np.asarray(weights, dtype=float)
    except (TypeError, ValueError):
        raise QPIKError(f"joint_weights must be {nv} finite positive numbers, got {weights!r}") from None
    if any(isinstance(v, (bool, np.bool_, str, bytes)) for v in np.ravel(np.asarray(weights, dtype=object))) or w.shape != (nv,) or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise QPIKError(f"joint_weights must be {nv} finite positive numbers, got {weights!r}")
    return w


def is_table_joint(name: str) -> bool:
    """True for the table's joints (``table_translation`` and the extra ones), False for the C-arm's."""
    return name.startswith("table_")


def joint_weights(system, weights=None, prefer: str | None = None) -> np.ndarray:
    """Per-joint weights (nq,) of the regularisation ``dq^T diag(w) dq`` (m⁻² or rad⁻²; 1 m ~ 1 rad).

    ``weights``: ``None`` (all 1), a sequence (nq,) in the order of ``system.joint_names``, or a dict by
    joint name (unnamed joints keep 1). ``prefer``: ``"table"`` multiplies the C-arm joints' weights by
    :data:`PREFERENCE_RATIO` (the table does the moving), ``"carm"`` the table joints' weights; ``None``
    leaves them.
    """
    names = system.joint_names
    if weights is None:
        w = np.ones(len(names))
    elif isinstance(weights, dict):
        unknown = set(weights) - set(names)
        if unknown:
            raise QPIKError(f"joint_weights names unknown joint(s) {sorted(unknown)}; joints: {', '.join(names)}")
        w = check_weights([weights.get(n, 1.0) for n in names], len(names))
    else:
        w = check_weights(weights, len(names))
    if prefer is None:
        return w
    if prefer not in ("table", "carm"):
        raise QPIKError(f"prefer must be 'table', 'carm' or None, got {prefer!r}")
    penalised = np.array([is_table_joint(n) == (prefer == "carm") for n in names])
    return np.where(penalised, PREFERENCE_RATIO * w, w)


def locked_indices(system, free: Sequence[str] | None) -> list[int]:
    """Indices of the joints not named in ``free`` (``None``: every joint free)."""
    if free is None:
        return []
    unknown = set(free) - set(system.joint_names)
    if unknown:
        raise QPIKError(f"free names unknown joint(s) {sorted(unknown)}; joints: {', '.join(system.joint_names)}")
    return [k for k, n in enumerate(system.joint_names) if n not in free]


def random_seeds(lower: np.ndarray, upper: np.ndarray, count: int, rng_seed: int = 0) -> list[np.ndarray]:
    """``count`` uniform draws (nq,) over the joint box (``numpy`` generator seeded with ``rng_seed``)."""
    rng = np.random.default_rng(rng_seed)
    return [rng.uniform(lower, upper) for _ in range(int(count))]
