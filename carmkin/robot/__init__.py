"""The same machine as Pinocchio and coal see it: the models of ``carmkin.model.urdf``, collision scene and pair policy,
the §4.4.3 validity report, and the closed form vs Pinocchio cross-check."""

from carmkin._lazy import submodules as _submodules

__getattr__ = _submodules(__name__, __path__)  # carmkin.robot.<module> after import carmkin, loaded on first use
