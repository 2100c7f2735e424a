"""Package data: ``carm_table.urdf.xacro``, the parametric description of the C-arm + table (see carmkin.model.urdf)."""
