"""A missing extra is one typed error naming the pip command, in the library and on the command line.

Each test hides the module the way an uninstalled package is hidden (``sys.modules[name] = None`` makes the
next import raise ``ModuleNotFoundError``) and checks the exact message and exit code.
"""

import sys

import numpy as np
import pytest

import carmkin
from carmkin import cli
from carmkin.errors import CarmkinError, InvalidParameterError, MissingExtraError
from carmkin.extras import EXTRAS, install_command, require


def hide(monkeypatch, *modules):
    for name in modules:
        monkeypatch.setitem(sys.modules, name, None)


@pytest.mark.parametrize("extra", sorted(EXTRAS))
def test_require_names_the_install_command(monkeypatch, extra):
    hide(monkeypatch, "numpy_fake_extra_module")
    with pytest.raises(MissingExtraError) as info:
        require("numpy_fake_extra_module", extra)
    assert isinstance(info.value, CarmkinError)
    assert f'python -m pip install "carmkin[{extra}]"' in str(info.value)
    assert info.value.module == "numpy_fake_extra_module" and info.value.extra == extra


def test_require_returns_the_module():
    assert require("numpy", "drr") is np


@pytest.mark.parametrize("module, extra", [(None, "drr"), ("numpy", "gpu"), ("numpy", None), (b"cv2", "drr"),
                                           ("not a name", "drr")])
def test_require_refuses_bad_arguments(module, extra):
    with pytest.raises(InvalidParameterError):
        require(module, extra)


def test_install_command():
    assert install_command("dicom") == 'python -m pip install "carmkin[dicom]"'


def test_load_ct_without_nibabel(monkeypatch):
    from carmkin.interop import drr

    hide(monkeypatch, "nibabel")
    with pytest.raises(MissingExtraError, match=r'carmkin\[drr\]'):
        drr.load_ct()


def test_renderer_without_nanodrr(monkeypatch):
    from carmkin.interop import drr

    hide(monkeypatch, "nanodrr", "nanodrr.data", "nanodrr.drr")
    volume = drr.Volume(np.zeros((2, 2, 2), dtype=np.float32), np.eye(4))
    with pytest.raises(MissingExtraError, match=r'carmkin\[drr\]'):
        drr.Renderer(carmkin.load_preset("siremobile-iso-c3d"), volume, np.eye(4))


def test_pydicom_missing(monkeypatch):
    from carmkin.interop import dicom_io

    hide(monkeypatch, "pydicom")
    with pytest.raises(MissingExtraError, match=r'python -m pip install "carmkin\[dicom\]"'):
        dicom_io.require_pydicom()


def test_cli_drr_without_nibabel_exits_2_with_one_line(monkeypatch, capsys):
    # before: "carmkin drr: internal error: ModuleNotFoundError: No module named 'nibabel'" and exit 3
    hide(monkeypatch, "nibabel")
    assert cli.main(["drr"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("carmkin drr: error:")
    assert 'python -m pip install "carmkin[drr]"' in err


def test_cli_reposition_without_opencv_exits_2(monkeypatch, capsys):
    hide(monkeypatch, "cv2")
    assert cli.main(["reposition", "simulate"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and 'python -m pip install "carmkin[reposition]"' in err
