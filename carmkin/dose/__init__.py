"""Skin dose of a procedure (issue 38): the entrance skin dose map on the patient's skin from irradiation events
(joints, technique, air kerma at the IRP) or from a dose report (RDSR) through a device preset.

``skin_dose(system, events, patient)`` -> :class:`DoseMap` (``.psd_gy``, ``.psd_point``, ``.cells``,
``.dose_gy``, ``.overlap``); ``read_rdsr(path, system)`` -> the report's events;
``plan_dose(system, plan, patient, Technique(...))`` -> the predicted map of planned views or biplane pairs (a model
of the air kerma, :mod:`carmkin.dose.plan`); the skin: the parametric body (``from_patient``), a CT's surface
(``from_ct``, ``from_surface``) or PySkinDose's phantoms (``plane``, ``cylinder``); ``choose_view`` /
``dose_aware_procedure``: the reachable view near a request that minimizes the predicted PSD
(:mod:`carmkin.dose.choice`). docs/dose.md states what is computed and assumed.
"""

from carmkin.dose.choice import Choice, Procedure, choose_view, dose_aware_procedure
from carmkin.dose.compute import DoseMap, EventDose, skin_dose
from carmkin.dose.event import IRP_FROM_ISOCENTRE, Beam, Event, beam
from carmkin.dose.plan import PlanDose, Technique, plan_dose, water_thickness
from carmkin.dose.rdsr import read_rdsr
from carmkin.dose.skin import Skin, cylinder, from_ct, from_patient, from_surface, plane

__all__ = ["IRP_FROM_ISOCENTRE", "Beam", "Choice", "DoseMap", "Event", "EventDose", "PlanDose", "Procedure", "Skin",
           "Technique", "beam", "choose_view", "cylinder", "dose_aware_procedure", "from_ct", "from_patient",
           "from_surface", "plan_dose", "plane", "read_rdsr", "skin_dose", "water_thickness"]
