"""The machinery behind :mod:`carmkin.analytic_ik`: the 5-DOF C-arm IK, the single-axis closed form of a
motorized table, and the damped-least-squares fallback at singular poses."""
