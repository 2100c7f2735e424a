"""The C-arc's own radius (``BodyGeometry.c_radius``): bodies only, kinematics unchanged.

Oracles: the closed-form FK (:meth:`CArmSystem.fk`, no URDF) places the source; the arc's centre is the
orbital axis at L along the principal axis (source Z), the arc's line off it by ``a2`` (source Y), as the
C-arm's geometry states (Fallavollita's DH, docs/kinematics.md). The boxes are read from Pinocchio's
collision model built from the generated URDF.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.model.urdf import C_SEGMENTS
from carmkin.presets import list_presets, load_preset, parse_preset, to_toml

#: Agreement of box placements with the closed-form geometry (m): float round-off through Pinocchio.
PLACEMENT_TOLERANCE = 1e-9


def _with_radius(system, c_radius):
    return system.replace(body=dataclasses.replace(system.body, c_radius=c_radius))


@pytest.mark.parametrize("name", list_presets())
def test_no_radius_is_the_source_to_orbital_axis_distance_exactly(name):
    system = load_preset(name)
    assert system.body.c_radius is None or name == "angio-lateral"
    base = system.replace(body=dataclasses.replace(system.body, c_radius=None))
    assert _with_radius(base, base.carm.source_to_orbital_axis).urdf() == base.urdf()


def _boxes(system, q):
    model, collision, _ = system.pinocchio()
    data, gdata = model.createData(), pin.GeometryData(collision)
    pin.updateGeometryPlacements(model, data, collision, gdata, pin.neutral(model) if q is None else q)
    return {g.name: (gdata.oMg[i].homogeneous, g.geometry) for i, g in enumerate(collision.geometryObjects)}


@settings(max_examples=15, deadline=None)
@given(extra=st.floats(0.0, 0.4), u=st.lists(st.floats(0.0, 1.0), min_size=10, max_size=10))
def test_a_larger_c_keeps_the_kinematics_and_lies_on_its_circle(extra, u):
    base = load_preset("angio-ceiling")
    L = base.carm.source_to_orbital_axis
    system = _with_radius(base, L + extra)
    q = base.lower + np.asarray(u[:base.nq]) * (base.upper - base.lower)
    m0, m1 = base.pinocchio()[0], system.pinocchio()[0]
    assert all(np.array_equal(a.homogeneous, b.homogeneous) for a, b in zip(m0.jointPlacements, m1.jointPlacements))
    source = base.fk(q)
    boxes = _boxes(system, q)
    to_source = np.linalg.inv(source)
    centre = np.array([0.0, base.carm.a2, L])
    rc = (L + extra) * np.cos(np.pi / C_SEGMENTS / 2)
    for i in range(C_SEGMENTS):
        p = (to_source @ boxes[f"dh_frame_6_{i}"][0])[:3, 3]
        assert abs(np.linalg.norm(p - centre) - rc) < PLACEMENT_TOLERANCE
        assert abs(p[0]) < PLACEMENT_TOLERANCE  # in the plane of the principal axis and the arc's line
    body = system.body
    far = [(to_source @ M)[:3, 3][2] + g.halfSide[2] for name, (M, g) in boxes.items() if name.startswith("detector")]
    assert max(far) == pytest.approx(L + L + extra, abs=PLACEMENT_TOLERANCE)  # detector bracket at the far end
    behind = extra - (body.source_housing[2] - 0.03)  # the housing reaches 0.03 m before the focal spot
    brackets = [name for name in boxes if name.startswith("xray_source")]
    if behind > 0:
        M, g = boxes["xray_source_1"]
        z = (to_source @ M)[:3, 3][2]
        assert z - g.halfSide[2] == pytest.approx(L - (L + extra), abs=PLACEMENT_TOLERANCE)  # the near end
        assert z + g.halfSide[2] == pytest.approx(-(body.source_housing[2] - 0.03), abs=PLACEMENT_TOLERANCE)
    else:
        assert brackets == ["xray_source_0"]


def test_a_c_that_misses_the_source_is_refused():
    base = load_preset("angio-ceiling")
    with pytest.raises(carmkin.CarmkinError, match=r"c_radius = 500 mm .* at least"):
        _with_radius(base, 0.5)
    with pytest.raises(carmkin.CarmkinError, match=r"BodyGeometry.c_radius"):
        _with_radius(base, -1.0)


def test_c_radius_mm_round_trips_through_a_preset_file():
    base = _with_radius(load_preset("angio-ceiling"), 1.05)
    text = to_toml(base)
    assert "c_radius_mm = 1050" in text
    assert parse_preset(text).body.c_radius == pytest.approx(1.05, abs=1e-12)
    assert "c_radius_mm" not in to_toml(load_preset("angio-ceiling"))
