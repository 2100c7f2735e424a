"""The box patient of the sweep tests (a module of its own: several test folders have a conftest.py)."""

from carmkin.robot.collision import Obstacle

#: A box patient on the preset's table top (surface at y = 0.15 m, Y0 down): 0.5 m wide, 0.3 m thick.
PATIENT = [Obstacle.box("patient", (0.5, 0.3, 1.6), center=(0.0, 0.0, 0.0))]
