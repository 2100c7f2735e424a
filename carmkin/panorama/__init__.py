"""The panorama planner (§4.4, Table 4.3): parallax-free panoramas from a reference X-ray pose, a planner
beside views, sweeps and reposition on the imaging geometry (:mod:`carmkin.imaging`) and the solvers.

- :mod:`.planner`: :class:`PanoramaPlanner` — a principal point in the panorama to joint moves, validity
  maps, whole plans (:class:`Plan` of :class:`Shot`);
- :mod:`.phantom`: the synthetic marker phantom and the simulated stitching check of parallax (§3.4);
- :mod:`.drr`: rendered panoramas on a CT (the ``drr`` extra);
- :mod:`.figure`: the validity-map figure (matplotlib), reached as :func:`plot_validity_map` on first use.
"""

from carmkin.errors import PanoramaError
from carmkin.panorama.planner import CATEGORIES, PanoramaPlanner, Plan, Shot, reference_configuration

__all__ = ["CATEGORIES", "PanoramaError", "PanoramaPlanner", "Plan", "Shot", "plot_validity_map",
           "reference_configuration"]


def plot_validity_map(planner, us, vs, categories, path=None, shots=()):
    """The validity-map figure (:func:`carmkin.panorama.figure.plot_validity_map`; matplotlib loads here)."""
    from carmkin.panorama.figure import plot_validity_map as draw

    return draw(planner, us, vs, categories, path, shots)
