"""The same machine as Pinocchio and coal see it: the models of ``carmkin.model.urdf``, collision scene and pair policy,
the §4.4.3 validity report, and the closed form vs Pinocchio cross-check."""
