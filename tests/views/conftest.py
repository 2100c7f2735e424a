"""Systems and maps shared by the view tests: the paper's 6-DOF preset, the C-arm alone (table translation
held), a non-isocentric C-arm and the motorized table, each with a parametric patient on the table."""

import dataclasses

import numpy as np
import pytest

import carmkin
from carmkin.patient import ParametricPatient
from carmkin.views import carm_alone, reach_map

#: A coarse integer-degree grid keeps the tests short; the benchmark runs the full 1° map.
PRIMARY = np.arange(-180, 180, 12)
SECONDARY = np.arange(-90, 91, 10)
TARGET = (0.0, 0.0, 0.0)


def _systems():
    six = carmkin.load_preset("siremobile-iso-c3d")
    return {
        "6-DOF": six,
        "C-arm alone": carm_alone(six),
        "non-isocentric": six.replace(carm=dataclasses.replace(six.carm, a1=0.04, a2=-0.06)),
        "motorized": carmkin.load_preset("siremobile-iso-c3d-motorized-table"),
    }


SYSTEMS = _systems()


@pytest.fixture(scope="session")
def maps():
    out = {}
    for name, system in SYSTEMS.items():
        patient = ParametricPatient.on_table(system)
        out[name] = (system, patient, reach_map(system, TARGET, PRIMARY, SECONDARY, patient=patient))
        m = out[name][2]
        print(f"\n{name}: {m.reachable.sum()} of {m.reachable.size} cells reachable")
    return out
