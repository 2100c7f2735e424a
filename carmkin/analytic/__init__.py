"""The machinery behind :mod:`carmkin.analytic_ik`: the 5-DOF C-arm IK, the single-axis closed form of a
motorized table, and the damped-least-squares fallback at singular poses."""

from carmkin._lazy import submodules as _submodules

__getattr__ = _submodules(__name__, __path__)  # carmkin.analytic.<module> after import carmkin, loaded on first use
