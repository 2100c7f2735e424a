"""Pictures of a plan and where things are (docs/views.md): ``carmkin views plan --png/--html`` draws the table,
the patient, the C-arm, the beam and the target; ``carmkin view --patient`` puts the patient in the viewer; the
text says where the target and the table top are in the table frame."""

from __future__ import annotations

import base64
import re

import numpy as np
import pytest
import umsgpack

import carmkin
from carmkin.cli import main
from carmkin.commands import _scene
from carmkin.patient import ParametricPatient

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")


def page_paths(html: str) -> set[str]:
    """Paths of the meshcat objects a static page sets."""
    blobs = re.findall(r'data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"', html)
    commands = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    return {c.get("path", "") for c in commands if c.get("type") == "set_object"}


def test_views_plan_writes_a_figure_and_a_page_with_patient_and_target(tmp_path, capsys):
    png, html = tmp_path / "plan.png", tmp_path / "plan.html"
    assert main(["views", "plan", "--primary-deg", "30", "--secondary-deg", "20", "--png", str(png),
                 "--html", str(html)]) == 0
    out = capsys.readouterr().out
    assert f"wrote {png}" in out and f"wrote {html}" in out
    from PIL import Image

    assert Image.open(png).size[0] > 500
    paths = page_paths(html.read_text())
    assert any("/patient/" in p for p in paths) and any(p.endswith("/target") for p in paths)


def test_the_scene_figure_puts_the_target_where_it_is():
    from carmkin.views import View, plan_view

    patient = ParametricPatient.on_table(SYSTEM)
    target = np.array([0.02, -0.05, 0.1])
    plan = plan_view(SYSTEM, View.from_angles(30, 20, target), patient)
    fig = carmkin.plots.scene_figure(SYSTEM, plan.q, patient, target)
    side, end = fig.axes
    for ax, across in ((side, 2), (end, 0)):
        marks = [line for line in ax.get_lines() if line.get_label() == "target"]
        assert len(marks) == 1
        np.testing.assert_allclose(np.ravel(marks[0].get_data()), [target[across] * 1e3, target[1] * 1e3])
        assert any(p.get_label() == "patient" for p in ax.patches)
        source = [line for line in ax.get_lines() if line.get_label() == "source"][0]
        np.testing.assert_allclose(np.ravel(source.get_data()), SYSTEM.fk(plan.q)[[across, 1], 3] * 1e3, atol=1e-9)


def test_the_table_top_is_where_the_patient_lies():
    patient = ParametricPatient.on_table(SYSTEM)
    lowest = max(o.pose[1, 3] + o.size[0] for o in patient.obstacles() if o.shape == "capsule")
    assert _scene.table_top_y(SYSTEM) == pytest.approx(lowest, abs=1e-6)  # the back's capsules touch the top
    text = _scene.describe_scene(SYSTEM, (0.0, _scene.table_top_y(SYSTEM) - 0.05, 0.0), patient, "HFS")
    assert "50.0 mm above the table top" in text and "parametric, 1750 mm, 75 kg, HFS" in text


def test_view_draws_the_patient(tmp_path, capsys):
    html = tmp_path / "v.html"
    assert main(["view", "--patient", "parametric", "--patient-position", "FFS", "--html", str(html)]) == 0
    assert "patient: parametric, 1750 mm, 75 kg, FFS" in capsys.readouterr().out
    assert any("/patient/" in p for p in page_paths(html.read_text()))


# --- a collision the text reports is in the picture --------------------------------------------------------------
#: A configuration whose detector runs into the parametric patient's thighs (HFS, default size), and one clear of it.
COLLIDING = [0.0, 0.0, 0.0, 0.2, np.pi / 2, 0.0]
CLEAR = [0.0, 0.2, 0.0, 0.1, 0.0, 0.0]


def colliding_bodies(q, patient) -> set[str]:
    """The oracle: bodies at or below 0 m from some C-arm part, by coal through the world's own distances."""
    from carmkin.world import World
    from carmkin.world.obstacles import link_of

    world = World(SYSTEM, patient)
    return {link_of(b) for (_, b), d in zip(world.pairs, world.distances(q=q).tolist()) if d <= 0.0}


@pytest.mark.parametrize("q", [COLLIDING, CLEAR], ids=["colliding", "clear"])
def test_the_scene_figure_outlines_in_red_exactly_the_bodies_hit(q):
    from matplotlib.colors import to_hex

    patient = ParametricPatient.on_table(SYSTEM)
    hit = colliding_bodies(q, patient)
    assert bool(hit) == (q is COLLIDING)
    fig = carmkin.plots.scene_figure(SYSTEM, q, patient)
    for ax in fig.axes:
        red = {p.get_gid() for p in ax.patches if to_hex(p.get_edgecolor()) == carmkin.plots.SCENE_COLOURS["collision"]}
        assert red == hit
        pair = [line for line in ax.get_lines() if "mm" in line.get_label()]
        assert len(pair) == 1 and pair[0].get_label().startswith("COLLISION" if hit else "closest:")
        assert (to_hex(pair[0].get_color()) == carmkin.plots.SCENE_COLOURS["collision"]) == bool(hit)


def collided_paths(html: str) -> set[str]:
    return {p.rsplit("/", 1)[-1] for p in page_paths(html) if "/distances/collided/" in p}


@pytest.mark.parametrize("q", [COLLIDING, CLEAR], ids=["colliding", "clear"])
def test_the_viewer_page_paints_every_body_hit_red(q):
    patient = ParametricPatient.on_table(SYSTEM)
    assert collided_paths(_scene.scene_page(SYSTEM, np.array(q), patient)) == colliding_bodies(q, patient)


def test_carmkin_view_says_and_draws_the_same_collision(tmp_path, capsys):
    page = tmp_path / "v.html"
    q = ",".join(f"{v:g}" for v in (0, 0, 0, 200, 90, 0))
    assert main(["view", "--q-mm-deg", q, "--patient", "parametric", "--html", str(page)]) == 0
    out = capsys.readouterr().out
    said = re.search(r"COLLISION with ([\w, ]+): drawn red", out)
    assert said, out
    named = set(said.group(1).split(", "))
    assert named == colliding_bodies(COLLIDING, ParametricPatient.on_table(SYSTEM)) == collided_paths(page.read_text())


# --- the C-arm's bodies, not only its frame origins (issue "The first hour, again": an end view drew a line
# through the patient while the text reported 150-240 mm of clearance) --------------------------------------
def carm_patches(ax) -> dict[str, object]:
    return {p.get_gid()[5:]: p for p in ax.patches if str(p.get_gid()).startswith("carm:")}


def test_the_scene_figure_draws_the_source_housing_and_the_detector_where_they_are():
    """The source lies inside the outline of its housing and the detector centre inside the detector's, in both
    views (the FK's source and detector: an independent route from the collision model's boxes)."""
    from matplotlib.path import Path as Outline

    q = np.array([0.0, 0.2, 0.0, 0.1, np.radians(30.0), np.radians(20.0)])
    fig = carmkin.plots.scene_figure(SYSTEM, q)
    T = SYSTEM.fk(q)
    source, detector = T[:3, 3], T[:3, 3] + SYSTEM.carm.source_to_detector * T[:3, 2]
    for ax, axis in zip(fig.axes, (2, 0)):
        parts = carm_patches(ax)
        assert {"xray_source_0", "detector_0"} <= set(parts) and len(parts) >= 10
        housing = Outline(parts["xray_source_0"].get_xy())
        assert housing.contains_point((source[axis] * 1e3, source[1] * 1e3))
        panel = [Outline(p.get_xy()) for n, p in parts.items() if n.startswith("detector")]
        # the detector centre lies on the detector's face: inside or on the outline of one of its boxes
        assert any(o.contains_point((detector[axis] * 1e3, detector[1] * 1e3), radius=1.0) for o in panel)


@pytest.mark.parametrize("q", [COLLIDING, CLEAR], ids=["colliding", "clear"])
def test_the_scene_figure_fills_red_exactly_the_carm_parts_in_collision(q):
    from matplotlib.colors import to_hex

    from carmkin.world import World

    patient = ParametricPatient.on_table(SYSTEM)
    world = World(SYSTEM, patient)
    hit = {a for (a, _), d in zip(world.pairs, world.distances(q=q).tolist()) if d <= 0.0}
    fig = carmkin.plots.scene_figure(SYSTEM, q, patient)
    for ax in fig.axes:
        red = {n for n, p in carm_patches(ax).items()
               if to_hex(p.get_facecolor()) == carmkin.plots.SCENE_COLOURS["collision"]}
        assert red == hit and bool(red) == (q is COLLIDING)


# --- a failed plan's picture: the configuration in contact and the pair that fails (issue 42), not the nearest
# reachable view; the C-arm as its bodies, not the DH frames' skeleton -------------------------------------------
def test_the_scene_figure_draws_no_dh_skeleton():
    fig = carmkin.plots.scene_figure(SYSTEM, np.array(COLLIDING), ParametricPatient.on_table(SYSTEM))
    for ax in fig.axes:
        assert not any("DH" in line.get_label() for line in ax.get_lines())


def test_a_view_unreachable_by_contact_carries_the_configuration_its_reason_names():
    from carmkin.views import View, plan_view
    from carmkin.world import World

    patient = ParametricPatient.on_table(SYSTEM)
    plan = plan_view(SYSTEM, View.from_angles(0, 80, np.zeros(3)), patient, nearest=False)
    assert not plan.success and plan.binding == "contact" and plan.q_contact is not None
    assert np.all(SYSTEM.lower - 1e-9 <= plan.q_contact) and np.all(plan.q_contact <= SYSTEM.upper + 1e-9)  # round-off
    a, b, d = re.match(r"contact: (\S+) – (\S+) at (-?[\d.]+) mm", plan.reason).groups()
    world = World(SYSTEM, patient)  # an independent route: every pair's exact distance at q_contact
    distances = dict(zip(world.pairs, world.distances(q=plan.q_contact).tolist()))
    assert distances[(a, b)] * 1e3 == pytest.approx(float(d), abs=0.05)
    reachable = plan_view(SYSTEM, View.from_angles(30, 20, np.zeros(3)), patient, nearest=False)
    assert reachable.success and reachable.q_contact is None


def test_views_plan_draws_the_contact_of_an_unreachable_view(tmp_path, capsys, monkeypatch):
    from matplotlib.colors import to_hex

    drawn = {}
    real = carmkin.plots.scene_figure

    def spy(system, q, patient=None, target=None, path=None, title=""):
        drawn.update(q=np.array(q), title=title)
        return real(system, q, patient, target, path, title)

    monkeypatch.setattr(carmkin.plots, "scene_figure", spy)
    png = tmp_path / "plan.png"
    code = main(["views", "plan", "--primary-deg", "0", "--secondary-deg", "80", "--png", str(png),
                 "--json", str(tmp_path / "plan.json")])
    out = capsys.readouterr().out
    assert code == 1 and png.exists() and "in contact at q = " in out
    import json

    from carmkin.views import View, plan_view

    plan = plan_view(SYSTEM, View.from_angles(0, 80, np.zeros(3)), ParametricPatient.on_table(SYSTEM), nearest=False)
    np.testing.assert_allclose(drawn["q"], plan.q_contact, atol=1e-12)
    assert "UNREACHABLE: the configuration in contact" in drawn["title"]
    saved = json.loads((tmp_path / "plan.json").read_text())
    assert list(saved["contact_q"].values()) == pytest.approx(list(carmkin.commands._common.joints_json(
        SYSTEM, plan.q_contact).values()))
    fig = real(SYSTEM, drawn["q"], ParametricPatient.on_table(SYSTEM), np.zeros(3))
    part = re.match(r"contact: (\S+) –", plan.reason).group(1)
    for ax in fig.axes:
        assert to_hex(carm_patches(ax)[part].get_facecolor()) == carmkin.plots.SCENE_COLOURS["collision"]
        assert any(line.get_label().startswith("COLLISION") for line in ax.get_lines())
