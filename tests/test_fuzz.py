"""Property-based fuzzing of the public API: wrong values, shapes, NaN/inf/huge/tiny/complex numbers,
non-rigid poses, junk types.

Every call must end in one of two ways:
- a correct answer (each entry point states what "correct" means below), or
- a typed error: a ``carmkin.CarmkinError`` subclass (issue 19: never a bare TypeError, not even one raised
  by carmkin's own code). An error from deep inside numpy, Pinocchio or Python (IndexError, AttributeError,
  TypeError) is a finding.
No warning may leak (warnings are errors here), and no call may hang: each is cut off after
``CALL_LIMIT_S`` seconds (a guard against unbounded work, not a timing assertion).

CI runs ``FUZZ_EXAMPLES`` examples per entry point; ``CARMKIN_FUZZ_SCALE=20`` runs twenty times as many
(see docs/architecture.md#tests).
"""

from __future__ import annotations

import os
import signal
import traceback
import warnings
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from strategies import poses

import carmkin
from carmkin.model.bounds import MAX_ANGLE, MAX_LENGTH, MAX_SETUP_DISTANCE

#: Examples per entry point in CI, and the multiplier for a long run.
FUZZ_EXAMPLES = 60
SCALE = int(os.environ.get("CARMKIN_FUZZ_SCALE", "1"))
#: A call that takes longer than this (s) is a finding: the cost of a call must be bounded.
CALL_LIMIT_S = 20

PRESET = carmkin.load_preset("siremobile-iso-c3d")
MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")


def fuzz(examples: int = FUZZ_EXAMPLES):
    return settings(max_examples=examples * SCALE, deadline=None, derandomize=True,
                    suppress_health_check=list(HealthCheck))


# --- junk -----------------------------------------------------------------------------------------------
specials = st.sampled_from([np.nan, np.inf, -np.inf, 1e300, -1e300, 1e-320, 0.0, -0.0, 1e16, 1e8])
junk_scalar = st.one_of(
    st.floats(), specials, st.complex_numbers(max_magnitude=1e3), st.integers(-2**70, 2**70),
    st.booleans(), st.none(), st.text(max_size=4),
)
number = st.one_of(st.floats(-10, 10, allow_nan=False), specials, st.complex_numbers(max_magnitude=10))


@st.composite
def junk_vector(draw, n: int):
    """Mostly the right length with a bad entry; sometimes a wrong shape, dtype or type."""
    kind = draw(st.integers(0, 5))
    if kind == 0:
        return [draw(junk_scalar) for _ in range(draw(st.integers(0, n + 2)))]
    if kind == 1:
        return np.zeros(draw(st.sampled_from([(), (n - 1,), (n + 1,), (n, 1), (2, n, 1), (0, n)])))
    if kind == 2:
        return draw(junk_scalar)
    value = draw(number)
    q = np.zeros(n, dtype=complex if isinstance(value, complex) else float)
    q[draw(st.integers(0, n - 1))] = value
    return q


@st.composite
def junk_pose(draw):
    """Non-rigid, non-finite, complex, huge or misshapen 4x4 poses."""
    T = draw(poses()).astype(float)
    kind = draw(st.integers(0, 6))
    if kind == 0:
        value = draw(number)
        T = T.astype(type(value) if isinstance(value, complex) else float)
        T[draw(st.integers(0, 2)), draw(st.integers(0, 3))] += value
    elif kind == 1:
        T[:3, 3] = draw(st.sampled_from([1e300, -1e300, 1e16, np.inf, np.nan, 1e8]))
    elif kind == 2:
        T = T.astype(complex)
        T[0, 0] += 1e-3j
    elif kind == 3:
        T[3] = [draw(st.one_of(st.floats(-10, 10, allow_nan=False), specials)) for _ in range(4)]
    elif kind == 4:
        return np.zeros(draw(st.sampled_from([(3, 4), (4,), (4, 4, 1), (16,), (0, 4, 4)])))
    elif kind == 5:
        return draw(junk_scalar)
    else:
        T[:3, :3] *= draw(st.floats(0.5, 2.0))
    return T


# --- the oracle -----------------------------------------------------------------------------------------
class _Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise _Timeout


def call(fn, *args, **kwargs):
    """Run ``fn``; return ("ok", value) or ("error", exc) for a typed error; fail the test otherwise."""
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(CALL_LIMIT_S)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            return "ok", fn(*args, **kwargs)
    except _Timeout:
        pytest.fail(f"{fn.__qualname__} took more than {CALL_LIMIT_S} s")
    except carmkin.CarmkinError as exc:
        assert str(exc), "a typed error must say what is wrong"
        return "error", exc
    except Exception as exc:  # noqa: BLE001 - everything else is a finding
        pytest.fail(f"{fn.__qualname__} raised {type(exc).__name__}: {exc}\n{traceback.format_exc()}")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def is_rigid(T, tol=1e-9) -> bool:
    T = np.asarray(T)
    R = T[..., :3, :3]
    return bool(np.all(np.isfinite(T)) and np.allclose(np.swapaxes(R, -1, -2) @ R, np.eye(3), atol=tol))


# --- entry points ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("system", [PRESET, MOTORIZED], ids=["plain", "motorized"])
@fuzz()
@given(data=st.data())
def test_fk(system, data):
    q = data.draw(junk_vector(system.nq))
    status, T = call(system.fk, q)
    if status == "ok":
        assert is_rigid(T) and T.shape[-2:] == (4, 4)


@pytest.mark.parametrize("system", [PRESET, MOTORIZED], ids=["plain", "motorized"])
@fuzz()
@given(data=st.data())
def test_motion_durations(system, data):
    """Joint speeds, moves and sweep timings: a duration ≥ 0 s, or a typed error."""
    from carmkin.model import motion

    status, _ = call(motion.JointMotion, data.draw(junk_scalar), data.draw(st.none() | junk_scalar), "orbital")
    status, duration = call(motion.move_duration, system.motion, np.zeros(system.nq), data.draw(junk_vector(system.nq)))
    if status == "ok":
        assert duration.seconds >= 0
    Q = np.zeros((3, system.nq))
    Q[-1, -1] = 0.1
    status, check = call(motion.follow, system.motion, Q, data.draw(st.none() | junk_scalar))
    if status == "ok":
        assert check.minimum_time > 0 and check.duration > 0


@fuzz()
@given(field=st.sampled_from(["length_offset", "orbital_offset", "a1", "a2", "source_to_detector",
                              "detector_width", "detector_height"]), value=junk_scalar)
def test_carm_geometry(field, value):
    status, carm = call(replace, PRESET.carm, **{field: value})
    if status == "ok":
        assert np.isfinite(getattr(carm, field)) and abs(getattr(carm, field)) <= MAX_LENGTH, "absurd magnitude accepted"
        system = PRESET.replace(carm=carm)
        assert is_rigid(system.fk(np.clip(np.zeros(6), system.lower, system.upper)))


@fuzz()
@given(field=st.sampled_from(["gamma1", "gamma2", "gamma3", "D1", "D2", "D3"]), value=junk_scalar)
def test_table_setup(field, value):
    status, setup = call(replace, PRESET.setup, **{field: value})
    if status == "ok":
        bound = MAX_SETUP_DISTANCE if field.startswith("D") else MAX_ANGLE
        assert np.isfinite(getattr(setup, field)) and abs(getattr(setup, field)) <= bound


@fuzz()
@given(T=st.one_of(junk_pose(), poses()))
def test_table_setup_from_pose(T):
    status, setup = call(carmkin.TableSetup.from_pose, T)
    if status == "ok":
        assert all(abs(v) <= MAX_SETUP_DISTANCE for v in (setup.D1, setup.D2, setup.D3)), "near-singular garbage"


@fuzz()
@given(lower=junk_scalar, upper=junk_scalar)
def test_joint_range(lower, upper):
    status, r = call(carmkin.JointRange, lower, upper)
    if status == "ok":
        assert np.isfinite(r.lower) and np.isfinite(r.upper) and r.lower <= r.upper


@fuzz()
@given(carm=junk_scalar, setup=junk_scalar)
def test_system_replace(carm, setup):
    status, system = call(PRESET.replace, carm=carm, setup=setup)
    assert status == "error", "a system with a junk carm/setup must be refused at construction"


@fuzz()
@given(name=st.one_of(st.text(max_size=30), junk_scalar))
def test_load_preset(name):
    status, system = call(carmkin.load_preset, name)
    if status == "ok":
        assert isinstance(system, carmkin.CArmSystem)


@fuzz()
@given(T=junk_pose(), q_current=st.one_of(st.none(), junk_vector(6)))
def test_analytic_ik(T, q_current):
    status, result = call(carmkin.analytic_ik.solve, PRESET, T, q_current=q_current)
    if status == "ok":
        assert result.solutions.shape == (2, 6)


@st.composite
def junk_batch(draw):
    """(N, 4, 4) batches (N may be 0) with one bad entry, or a misshapen array."""
    n = draw(st.integers(0, 3))
    Ts = np.stack([draw(poses()) for _ in range(n)]) if n else np.zeros((0, 4, 4))
    kind = draw(st.integers(0, 4))
    if kind == 0 and n:
        Ts[draw(st.integers(0, n - 1)), draw(st.integers(0, 2)), draw(st.integers(0, 3))] = draw(specials)
    elif kind == 1 and n:
        Ts = Ts.astype(complex) + 1e-3j
    elif kind == 2 and n:
        Ts[..., :3, :3] *= 1.01
    elif kind == 3:
        return np.zeros(draw(st.sampled_from([(n, 3, 4), (4, 4), (n, 16), (n, 4, 4, 1)])))
    return Ts


@pytest.mark.parametrize("system", [PRESET, MOTORIZED], ids=["plain", "motorized"])
@fuzz(30)
@given(Ts=junk_batch())
def test_analytic_ik_batch(system, Ts):
    status, result = call(carmkin.analytic_ik.solve_batch, system, Ts)
    if status == "ok":
        assert result.solutions.shape == (2, len(Ts), 6)


@fuzz(30)
@given(T=junk_pose())
def test_qp_ik(T):
    status, result = call(carmkin.qp_ik.solve, PRESET, T)
    if status == "ok":
        assert result.q.shape == (6,)


@pytest.mark.parametrize("system", [PRESET, MOTORIZED], ids=["plain", "motorized"])
@fuzz(30)
@given(data=st.data())
def test_validity(system, data):
    from carmkin.robot import validity

    q = data.draw(junk_vector(system.nq))
    margin = data.draw(st.one_of(st.just(0.0), junk_scalar))
    call(validity.check, system, q, margin=margin)


@fuzz()
@given(q=junk_vector(6), which=st.sampled_from(["classify", "measures", "jacobian", "det_jacobian"]))
def test_singularity(q, which):
    call(getattr(carmkin.singularity, which), PRESET, q)


@fuzz()
@given(name=junk_scalar)
def test_singularity_joint_index(name):
    status, index = call(carmkin.singularity.joint_index, name)
    if status == "ok":
        assert 0 <= index < 6


@fuzz()
@given(K=st.one_of(junk_pose(), st.just(PRESET.carm.intrinsics())), T=st.one_of(junk_pose(), poses()),
       X=st.one_of(junk_vector(3), st.just(np.array([[0.0, 0.0, 2.0]]))))
def test_imaging_project(K, T, X):
    call(carmkin.imaging.project, K, T, X)


@fuzz(20)
@given(length=st.one_of(junk_scalar, st.floats(-1, 2)), overlap=st.one_of(junk_scalar, st.floats(-1, 2)))
def test_panorama_plan(length, overlap):
    from carmkin.panorama import PanoramaPlanner

    call(PanoramaPlanner(PRESET).plan, length, overlap=overlap)


# --- issue 19: every entry point with its oracle (the quick slice of benchmarks/fuzz.py) -----------------
import fuzz_engine  # noqa: E402
import fuzz_entries  # noqa: E402
import fuzz_entries_junk  # noqa: E402
import fuzz_entries_more  # noqa: E402
import fuzz_entries_systems  # noqa: E402

#: Cases per entry point in CI (benchmarks/fuzz.py --cases 100000 is the long run).
SLICE_CASES = 40 * SCALE
ALL_ENTRIES = {**fuzz_entries.ENTRIES, **fuzz_entries_systems.ENTRIES, **fuzz_entries_more.ENTRIES,
               **fuzz_entries_junk.ENTRIES}


@pytest.mark.parametrize("name", [
    pytest.param(name, marks=pytest.mark.xfail(reason=fuzz_entries_systems.KNOWN[name], strict=False))
    if name in fuzz_entries_systems.KNOWN else name for name in ALL_ENTRIES])
def test_entry_point_right_or_refused(name):
    make, _ = ALL_ENTRIES[name]
    tally = fuzz_engine.run({name: (make, 1)}, SLICE_CASES, seed=1)[name]
    assert tally.cases == SLICE_CASES
    assert fuzz_engine.findings(tally) == 0, "\n".join(tally.examples)
    assert tally.counts["ok"] > 0, "no case reached the oracle: the generator only makes junk"
