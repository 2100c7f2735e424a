"""Skin dose of a procedure (issue 38): the entrance skin dose map on the patient's skin from irradiation events
(joints, technique, air kerma at the IRP) or from a dose report (RDSR) through a device preset.

``skin_dose(system, events, patient)`` -> :class:`DoseMap` (``.psd_gy``, ``.psd_point``, ``.cells``,
``.dose_gy``, ``.overlap``); ``read_rdsr(path, system)`` -> the report's events. docs/dose.md states what is
computed and assumed.
"""

from carmkin.dose.compute import DoseMap, EventDose, skin_dose
from carmkin.dose.event import IRP_FROM_ISOCENTRE, Beam, Event, beam
from carmkin.dose.rdsr import read_rdsr
from carmkin.dose.skin import Skin, cylinder, from_patient, plane

__all__ = ["IRP_FROM_ISOCENTRE", "Beam", "DoseMap", "Event", "EventDose", "Skin", "beam", "cylinder",
           "from_patient", "plane", "read_rdsr", "skin_dose"]
