"""Shared sweeps: the preset's 190° orbital sweep around its isocentre, with a box patient on the table."""

import pytest
from strategies import PRESET

from carmkin.robot.collision import Obstacle
from carmkin.sweeps import plan_sweep

#: A box patient on the preset's table top (surface at y = 0.15 m, Y0 down): 0.5 m wide, 0.3 m thick.
PATIENT = [Obstacle.box("patient", (0.5, 0.3, 1.6), center=(0.0, 0.0, 0.0))]


@pytest.fixture(scope="session")
def preset_sweep():
    return plan_sweep(PRESET, [0.0, 0.0, 0.0], arc_deg=190.0, n_views=100, patient=PATIENT)
