"""Applications of the chain: the 5- vs 6-DOF workspace study (§4.6.1) and the multi-DOF table study."""

from carmkin._lazy import submodules as _submodules

__getattr__ = _submodules(__name__, __path__)  # carmkin.studies.<module> after import carmkin, loaded on first use
