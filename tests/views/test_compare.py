"""compare_maps: the C-arm alone, with the table translation, with a motorized table — each map's reachable
cells checked by FK and a fresh scene of its own system (the motorized one at its sampled table poses), and
the workspaces nested as their joints are."""

import numpy as np
import pytest

import carmkin
from carmkin.errors import ViewError
from carmkin.patient import ParametricPatient
from carmkin.robot import validity
from carmkin.world import World
from carmkin.views import DEFAULT_MARGIN, carm_alone, compare_maps, reach_map
from carmkin.views.compare import table_samples

PRIMARY, SECONDARY = np.arange(-90, 91, 15), np.arange(-45, 46, 15)


@pytest.fixture(scope="module")
def compared():
    system = carmkin.load_preset("siremobile-iso-c3d")
    motorized = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    patient = ParametricPatient.on_table(system)
    maps = compare_maps(system, (0.0, 0.0, 0.0), PRIMARY, SECONDARY, patient, motorized=motorized)
    return (carm_alone(system), system, motorized), patient, list(maps.values())


def test_every_reachable_cell_of_each_system_is_right(compared):
    systems, patient, maps = compared
    checked = 0
    for system, m in zip(systems, maps):
        scene = World(system, patient.obstacles())
        samples = np.array(table_samples(system)) if system.table.joints else None
        for i, j in zip(*np.nonzero(m.reachable)):
            q = m.q[i, j]
            T = system.fk(q)
            assert np.linalg.norm(T[:3, 2] - m.directions[i, j]) < 1e-9
            assert validity.check(system, q, margin=DEFAULT_MARGIN, world=scene).reachable
            if samples is not None:  # the table joints are those of one sample
                table = [k for k, n in enumerate(system.joint_names) if n.startswith("table_") and k]
                assert np.min(np.abs(samples[:, table] - q[table]).max(axis=1)) == 0.0
            checked += 1
    print(f"\n{checked} reachable cells of the three systems checked")
    assert checked > 100


def test_the_workspaces_are_nested(compared):
    _, _, (alone, six, motorized) = compared
    assert np.all(six.reachable[alone.reachable]) and np.all(motorized.reachable[six.reachable])
    assert alone.fraction < six.fraction < motorized.fraction


def test_table_samples_are_checked():
    system = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    for junk in ([np.zeros(6)], [np.full(system.nq, np.nan)], [], [np.r_[0.0, 5.0, np.zeros(system.nq - 2)]]):
        with pytest.raises(ViewError, match="table_samples"):
            reach_map(system, (0, 0, 0), [0], [0], table_samples=junk)
