"""3D sweeps: plan a collision-free cone-beam CT orbit for any C-arm and table (:mod:`.plan`), hand its
geometry to RTK, ASTRA, TIGRE and DICOM (:mod:`.export`), and simulate and reconstruct it with RTK
(:mod:`.reconstruct`, the ``cbct`` extra). Library units: m and rad, table frame 0.
"""

from .plan import DEFAULT_MARGIN, Limit, ShortScan, Sweep, SweepFailure, plan_sweep

__all__ = ["DEFAULT_MARGIN", "Limit", "ShortScan", "Sweep", "SweepFailure", "plan_sweep", "astra_vectors",
           "tigre_geometry", "rtk_geometry", "write_rtk_xml", "positioner_angles"]

_EXPORTS = ("astra_vectors", "tigre_geometry", "rtk_geometry", "write_rtk_xml", "positioner_angles")


def __getattr__(name):  # exports load on first use (RTK is optional)
    if name in _EXPORTS:
        from . import export

        return getattr(export, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
