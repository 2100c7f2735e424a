"""The parametric patient: volumes from Winter's masses and densities (capsule volume written out here), the
body resting on the table in every Patient Position, head where DICOM puts it, typed errors."""

import math

import coal
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.errors import PatientModelError
from carmkin.imaging.projection import PATIENT_POSITIONS
from carmkin.patient import ParametricPatient
from carmkin.patient.body import DENSITIES, MASS_FRACTIONS

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")


def _capsule_volume(radius, length):
    return math.pi * radius ** 2 * (length - 2 * radius) + 4.0 / 3.0 * math.pi * radius ** 3


@settings(max_examples=40)
@given(st.floats(1.0, 2.2), st.floats(20.0, 200.0))
def test_segment_volumes_are_mass_over_density(height, mass):
    patient = ParametricPatient(height, mass)
    for s in patient.segments:
        kind = s.name.rsplit("_", 1)[0] if s.name.endswith(("_left", "_right")) else s.name
        expected = MASS_FRACTIONS[kind] * mass / DENSITIES[kind]
        if s.shape == "box":
            volume = float(np.prod(s.extents))
        else:
            length = float(np.linalg.norm(np.subtract(s.b, s.a)))
            if 2 * s.radius >= length - 1e-12:  # a ball: the segment is shorter than its volume asks
                continue
            volume = _capsule_volume(s.radius, length)
        assert volume == pytest.approx(expected, rel=1e-9), s.name


@pytest.mark.parametrize("position", list(PATIENT_POSITIONS))
def test_rests_on_the_table_in_every_position(position):
    patient = ParametricPatient.on_table(SYSTEM, position=position)
    table = coal.Box(*SYSTEM.table.top_size)
    tf = coal.Transform3s(np.eye(3), np.array(SYSTEM.table.top_center))
    distances = []
    for o in patient.obstacles():
        request, result = coal.DistanceRequest(), coal.DistanceResult()
        request.enable_signed_distance = True
        distances.append(coal.distance(o.geometry(), coal.Transform3s(o.pose[:3, :3], o.pose[:3, 3]), table, tf,
                                       request, result))
    assert min(distances) == pytest.approx(0.0, abs=1e-6)
    head = next(o for o in patient.obstacles() if o.name == "patient_head").pose[2, 3]
    assert np.sign(head) == (1 if position.startswith("HF") else -1)


def test_heavier_is_thicker_not_longer():
    light, heavy = ParametricPatient(1.75, 60.0), ParametricPatient(1.75, 110.0)
    assert np.ptp(light.surface_points()[:, 2]) == pytest.approx(np.ptp(heavy.surface_points()[:, 2]), abs=0.02)
    assert np.ptp(heavy.surface_points()[:, 1]) > np.ptp(light.surface_points()[:, 1])


@pytest.mark.parametrize("kwargs", [dict(height="tall"), dict(height=float("nan")), dict(mass=-3.0),
                                    dict(position="XYZ"), dict(origin=(0, 0)), dict(arms="folded")])
def test_bad_input_is_refused(kwargs):
    with pytest.raises(PatientModelError):
        ParametricPatient(**kwargs)
