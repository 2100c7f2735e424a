"""Shared sweeps: the preset's 190° orbital sweep around its isocentre, with a box patient on the table."""

import pytest
from strategies import PRESET

from sweep_patient import PATIENT

from carmkin.sweeps import plan_sweep


@pytest.fixture(scope="session")
def preset_sweep():
    return plan_sweep(PRESET, [0.0, 0.0, 0.0], arc_deg=190.0, n_views=100, patient=PATIENT)
