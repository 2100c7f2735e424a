"""Systems shared by the view tests (a module of its own: several test folders have a conftest.py, so
``from conftest import ...`` would find another folder's): the paper's 6-DOF preset, the C-arm alone (table
translation held), a non-isocentric C-arm and the motorized table."""

import dataclasses

import numpy as np

import carmkin
from carmkin.views import carm_alone
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


