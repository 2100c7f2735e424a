"""Which joint causes which pixels in §4.6.2: per-joint image sensitivity and residual decomposition.

For a task, the image of the 16 table-top corners is a function of the true joints; its Jacobian
``J_j = ∂m/∂q_j`` (central differences of :meth:`CArmSystem.fk` + projection, per corner, px per m or per
rad) at the reference configuration gives each joint's **sensitivity**: the RMS over the corners of
``|J_j|``, reported in px per mm or px per degree. The **residual decomposition** splits the final
image error to first order, ``m(q_final) − m(q_ref) ≈ Σ_j J_j Δq_j`` with ``Δq = q_final − q_ref``: joint
j's share is the RMS over the corners of ``|J_j Δq_j|`` (px), beside its mean |Δq_j| (mm or degrees) and
the linearisation's residual (what the first order misses).
"""

from __future__ import annotations

import math

import numpy as np

#: Central-difference step (m or rad) of the image Jacobian.
STEP = 1e-6


def image_jacobian(system, q, points) -> np.ndarray:
    """(nq, N, 2): pixels of the table-frame ``points`` (N, 3) per unit of each joint at ``q``."""
    from carmkin.imaging import project

    K, q = system.carm.intrinsics(), np.asarray(q, dtype=float)
    out = np.empty((system.nq, len(points), 2))
    for j in range(system.nq):
        dq = np.zeros(system.nq)
        dq[j] = STEP
        out[j] = (project(K, system.fk(q + dq), points) - project(K, system.fk(q - dq), points)) / (2 * STEP)
    return out


def _unit_scale(system) -> np.ndarray:
    """Per joint: metres or radians per displayed unit (mm or degree)."""
    return np.where(system.prismatic, 1e-3, math.radians(1.0))


def decompose(system, tasks) -> dict:
    """Per joint (names in ``system.joint_names``): ``sensitivity`` px per mm / degree, ``residual``
    mean |Δq| in mm / degrees and ``pixels`` RMS share (px), over the successful ``tasks``
    (:class:`~.repositioning.Task`), and ``linear_residual``: RMS of what the first order misses (px)."""
    ok = [t for t in tasks if t.success]
    scale = _unit_scale(system)
    sensitivity, residual, share, missed = [], [], [], []
    for t in ok:
        J = image_jacobian(system, t.q_reference, t.markers)
        dq = t.q_final - t.q_reference
        sensitivity.append(np.sqrt(np.mean(np.sum(J**2, axis=2), axis=1)) * scale)
        residual.append(np.abs(dq) / scale)
        parts = J * dq[:, None, None]
        share.append(np.sqrt(np.mean(np.sum(parts**2, axis=2), axis=1)))
        from carmkin.imaging import project

        K = system.carm.intrinsics()
        exact = project(K, t.T_final, t.markers) - project(K, t.T_reference, t.markers)
        missed.append(np.sqrt(np.mean(np.sum((exact - parts.sum(axis=0)) ** 2, axis=1))))
    if not ok:
        nan = np.full(system.nq, np.nan)
        return {"joints": system.joint_names, "sensitivity": nan, "residual": nan, "pixels": nan,
                "linear_residual": math.nan}
    return {"joints": system.joint_names, "sensitivity": np.mean(sensitivity, axis=0),
            "residual": np.mean(residual, axis=0), "pixels": np.sqrt(np.mean(np.square(share), axis=0)),
            "linear_residual": float(np.sqrt(np.mean(np.square(missed))))}


def format_decomposition(system, table: dict) -> str:
    """The per-joint table: sensitivity, mean residual and image share."""
    lines = [f"{'joint':<20}{'sensitivity':>18}{'mean |residual|':>18}{'image share (px RMS)':>22}"]
    for name, prismatic, s, r, p in zip(table["joints"], system.prismatic, table["sensitivity"], table["residual"],
                                        table["pixels"]):
        unit = "mm" if prismatic else "deg"
        lines.append(f"{name:<20}{s:11.2f} px/{unit:<3}{r:13.3f} {unit:<4}{p:18.2f}")
    lines.append(f"{'first-order residual':<20}{'':>36}{table['linear_residual']:18.2f}")
    return "\n".join(lines)


def plot_decomposition(system, table: dict):
    """Bar chart (matplotlib Figure): per joint, the sensitivity and the image share."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 3.2))
    left, right = fig.subplots(1, 2)
    names = list(table["joints"])
    units = ["px/mm" if p else "px/deg" for p in system.prismatic]
    left.bar(names, table["sensitivity"], color="tab:blue")
    left.set_title("image sensitivity per joint unit")
    left.set_xticks(range(len(names)), [f"{n}\n{u}" for n, u in zip(names, units)], fontsize=7)
    right.bar(names, table["pixels"], color="tab:red")
    right.set_title("share of the final image error (px RMS)")
    right.set_xticks(range(len(names)), names, fontsize=7)
    fig.tight_layout()
    return fig
