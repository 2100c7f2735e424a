"""Maps shared by the view tests: each system of view_systems.py with a parametric patient on the table."""

import pytest
from view_systems import PRIMARY, SECONDARY, SYSTEMS, TARGET

from carmkin.patient import ParametricPatient
from carmkin.views import reach_map


@pytest.fixture(scope="session")
def maps():
    out = {}
    for name, system in SYSTEMS.items():
        patient = ParametricPatient.on_table(system)
        out[name] = (system, patient, reach_map(system, TARGET, PRIMARY, SECONDARY, patient=patient))
        m = out[name][2]
        print(f"\n{name}: {m.reachable.sum()} of {m.reachable.size} cells reachable")
    return out
