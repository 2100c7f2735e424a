"""The machinery behind :mod:`carmkin.qp_ik`: tasks, targets, limits (constraints as objects), QP
backends, one QP step, the iteration and redundant chains."""
