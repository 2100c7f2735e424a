"""The same machine as Pinocchio and coal see it: xacro → URDF → models, collision scene and pair policy,
the §4.4.3 validity report, and the closed form vs Pinocchio cross-check."""
