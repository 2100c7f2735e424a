"""The dissertation's experiments, simulated with one stated error model (issue 21).

:mod:`.error_model` states the CamC system's error sources once, each with its source or "assumption";
:mod:`.measure` is how the simulated system sees the room (filtered camera stream, X-ray centroids,
the C-arm's sag and the Virtual Detector Plane); the experiments follow the seed's definitions:
:mod:`.repositioning` (§4.6.2), :mod:`.fit` (the error model's free parameters fitted to §4.6.2),
:mod:`.joints` (per-joint image sensitivity and residual decomposition), :mod:`.stitching` (§4.6.3,
Table 4.6), :mod:`.chapter3` (Tables 3.1 and 3.2) and :mod:`.verdict` (one table: seed vs simulation for
every number). Lengths in m and angles in rad inside; tables print mm, degrees and px.

This package sits above :mod:`carmkin.reposition` and :mod:`carmkin.imaging` (it uses both) and below
the commands (``carmkin reproduce``).
"""
