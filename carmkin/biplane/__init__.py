"""Biplane C-arms (issue 30): two planes, frontal and lateral, on one table about one isocentre.

The device is a value beside the model (:class:`carmkin.model.biplane.Biplane`: two
:class:`~carmkin.CArmSystem` s, one joint vector), read from a biplane preset by
:func:`carmkin.presets.read_biplane`; this room adds what needs the collision world and the view planner:

* :func:`load_biplane` — a biplane preset, its planes checked clear of each other at rest (:func:`check_rest`);
* :class:`BiplaneWorld` — each plane's :class:`carmkin.world.World` and the clearance between the planes;
* :func:`plan_biplane` — a frontal and a lateral view planned at once, the planes clear of each other and of
  the patient (:class:`BiplanePlan`, or the typed :class:`Failure`); :func:`lateral_view` turns a view.

It stands at the studies' layer: it runs the view planner for each plane, and planners do not import each
other (docs/biplane.md, "Where it lives").
"""

from carmkin.model.biplane import ISOCENTRE_TOLERANCE, Biplane, default_rest

from .plan import BiplanePlan, Failure, lateral_view, plan_biplane
from .world import BiplaneWorld, Clearance, check_rest, load_biplane

__all__ = ["ISOCENTRE_TOLERANCE", "Biplane", "BiplanePlan", "BiplaneWorld", "Clearance", "Failure", "check_rest",
           "default_rest", "lateral_view", "load_biplane", "plan_biplane"]
