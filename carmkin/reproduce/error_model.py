"""One error model of the CamC system (camera-augmented mobile C-arm), stated once.

Every experiment of :mod:`carmkin.reproduce` draws its errors from an :class:`ErrorModel`; every parameter
is listed in :data:`PROVENANCE` with its source in the dissertation or the word "assumption". The two
parameters the seed does not pin down and which its §4.6.2 numbers constrain — the camera's corner noise
and the operator's stopping precision — are the free parameters of :mod:`carmkin.reproduce.fit`.

Error sources, in the order a measurement meets them:

* **video corners**: independent Gaussian noise (px) on every corner the camera finds (§3.3.2);
* **the display filter**: "continuous guidance" shows the mean of the last ``frames`` pose estimates;
* **camera–X-ray calibration** (§2.2.2.1, [50]): the camera's optical centre is aligned with the X-ray
  source up to a fixed offset and rotation, which the system believes to be zero;
* **table calibration** (§3.3.3): the pattern is mounted with a rotation error and the marker→table
  rotation is calibrated from table translations seen by the same noisy camera;
* **the operator** (§4.6.2): a manual move of Δ stops at ``Δ (1 + relative N₁) + absolute N₂``
  (:class:`carmkin.reposition.world.OperatorModel`), absolute terms per joint kind;
* **joint read-out**: the readings the model is built from (eq. 4.3) carry Gaussian noise;
* **X-ray centroids**: marker centroids / corners extracted from X-ray images carry Gaussian noise (px);
* **C-arm sag** (§2.2.2.1): the detector shifts in its plane by ``sag`` per unit of gravity across the
  beam, relative to the calibrated (beam vertical) pose; the Virtual Detector Plane undoes it from four
  markers on the mirror (:mod:`carmkin.reproduce.measure`);
* **phantom plane distance** (§3.3.5, §4.6.3): "measured manually", with Gaussian error.

Detector pixels are square (issue 21: the preset's 230 mm square on 800 × 600 would make them 0.29 × 0.38 mm
and no source says so): :func:`square_pixel_system` keeps the width and the 800 × 600 image and sets the
height to 230 · 600 / 800 = 172.5 mm. Lengths in m, angles in rad.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import SimulationError
from carmkin.validation import MAX_DISTANCE, integer, real_scalar

#: Largest count (tasks, procedures, repeats, resamples, frames, calibration positions) a study accepts: a
#: guard against a typo that would run for days (or a float such as 1e300 read as a count), not a bound of the
#: seed's protocol.
MAX_COUNT = 100_000
#: Upper bounds of the error model's parameters by unit: px (a noise beyond the 800 px image is no camera),
#: rad (a half turn), m (validation.MAX_DISTANCE), and the operator's relative stop error (ten times the move).
PARAMETER_BOUNDS = {"px": 800.0, "rad": math.pi, "m": MAX_DISTANCE, "": 10.0}

#: Where each parameter's value comes from (shown by ``carmkin reproduce --model`` and docs/fidelity.md).
PROVENANCE = {
    "corner_noise_px": "free: fitted to §4.6.2 (the seed cites [224, 225] for the pose error, gives no number)",
    "frames": "assumption: the display averages the last 5 video estimates (the seed says 'continuous')",
    "camera_xray_offset": "assumption: 1 mm residual misalignment of camera centre and source ([50])",
    "camera_xray_rotation": "assumption: 0.1 deg residual rotation of the camera-X-ray calibration ([50])",
    "mount_error": "assumption: pattern edges 'roughly parallel' to the table (§3.3.1): 2 deg",
    "calibration_positions": "assumption: 6 table positions for the §3.3.3 calibration",
    "operator_relative": "free: scaled with the operator's stop errors (default 10 % of each manual move)",
    "operator_translation": "free: fitted to §4.6.2 with operator_rotation (same scale); default 1 mm",
    "operator_rotation": "free: fitted to §4.6.2 with operator_translation (same scale); default 0.2 deg",
    "readout_translation": "assumption: 0.5 mm joint read-out (ruler / encoder) at the model's pose",
    "readout_rotation": "assumption: 0.1 deg joint read-out (scale / encoder) at the model's pose",
    "xray_noise_px": "assumption: 0.3 px centroid / corner extraction ('subpixel accuracy', §3.4.1, §4.6.2)",
    "sag": "assumption: 2 mm detector shift per g across the beam (order of §2.2.2.2's 1.67 mm without VDP)",
    "plane_distance": "assumption: 1 mm error of the manually measured phantom distance (§3.4.1, §4.6.3)",
    "thresholds": "source: §4.6.2 'below 2 mm for translational joints and 0.5 deg for rotational joints'",
    "square pixels": "assumption: 230 mm wide detector on 800 x 600 px, square pixels (issue 21)",
}


#: The model's counts, and the unit of each other parameter (px, m or rad; none: a ratio).
COUNTS = ("frames", "calibration_positions")
UNITS = {"corner_noise_px": "px", "xray_noise_px": "px", "camera_xray_offset": "m", "operator_translation": "m",
         "readout_translation": "m", "sag": "m", "plane_distance": "m", "camera_xray_rotation": "rad",
         "mount_error": "rad", "operator_rotation": "rad", "readout_rotation": "rad"}


@dataclass(frozen=True)
class ErrorModel:
    """The CamC system's error sources (SI units; see the module docstring and :data:`PROVENANCE`).

    ``corner_noise_px`` (px), ``frames`` (estimates averaged per reading), ``camera_xray_offset`` (m),
    ``camera_xray_rotation`` (rad), ``mount_error`` (rad), ``calibration_positions``, ``operator_relative``,
    ``operator_translation`` (m), ``operator_rotation`` (rad), ``readout_translation`` (m),
    ``readout_rotation`` (rad), ``xray_noise_px`` (px), ``sag`` (m per g), ``plane_distance`` (m).
    """

    corner_noise_px: float = 0.2
    frames: int = 5
    camera_xray_offset: float = 0.001
    camera_xray_rotation: float = math.radians(0.1)
    mount_error: float = math.radians(2.0)
    calibration_positions: int = 6
    operator_relative: float = 0.1
    operator_translation: float = 0.001
    operator_rotation: float = math.radians(0.2)
    readout_translation: float = 0.0005
    readout_rotation: float = math.radians(0.1)
    xray_noise_px: float = 0.3
    sag: float = 0.002
    plane_distance: float = 0.001

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value, name = getattr(self, f.name), f"ErrorModel.{f.name}"
            if f.name in COUNTS:
                integer(value, name, low=1, high=MAX_COUNT, error=SimulationError)
            else:
                unit = UNITS.get(f.name, "")
                real_scalar(value, name, low=0.0, high=PARAMETER_BOUNDS[unit], error=SimulationError, unit=unit)

    @classmethod
    def exact(cls, **changes) -> "ErrorModel":
        """Every error source at zero (one filtered frame), then ``changes``: the plumbing's exact case."""
        zero = {f.name: 0.0 for f in dataclasses.fields(cls) if f.name not in ("frames", "calibration_positions")}
        return cls(**{**zero, "frames": 1, **changes})

    def replace(self, **changes) -> "ErrorModel":
        return dataclasses.replace(self, **changes)

    def with_operator_scale(self, scale: float) -> "ErrorModel":
        """The operator's stop errors scaled by ``scale`` from the defaults (10 %, 1 mm, 0.2°)."""
        return self.replace(operator_relative=scale * ErrorModel.operator_relative,
                            operator_translation=scale * ErrorModel.operator_translation,
                            operator_rotation=scale * ErrorModel.operator_rotation)

    @property
    def operator_scale(self) -> float:
        return self.operator_translation / ErrorModel.operator_translation

    def operator(self):
        """The :class:`carmkin.reposition.world.OperatorModel` of these stop errors."""
        from carmkin.reposition.world import OperatorModel

        return OperatorModel(self.operator_relative, self.operator_translation, self.operator_rotation)

    def readout(self, system, q, rng: np.random.Generator) -> np.ndarray:
        """Joint readings (nq,) of the true joints ``q``: Gaussian read-out noise per joint kind."""
        sigma = np.where(system.prismatic, self.readout_translation, self.readout_rotation)
        return np.asarray(q, dtype=float) + sigma * rng.normal(size=system.nq)

    def camera_offset(self, rng: np.random.Generator) -> np.ndarray:
        """The camera's pose in the X-ray source frame (4, 4): the calibration's residual, random directions."""
        from carmkin.reposition.world import random_rotation

        T = np.eye(4)
        T[:3, :3] = random_rotation(rng, self.camera_xray_rotation)
        direction = rng.normal(size=3)
        T[:3, 3] = self.camera_xray_offset * direction / np.linalg.norm(direction)
        return T

    def table(self) -> list[tuple[str, str, str]]:
        """(parameter, value in mm / deg / px, provenance) rows."""
        rows = []
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if UNITS.get(f.name) == "m":
                text = f"{value * 1e3:g} mm"
            elif UNITS.get(f.name) == "rad":
                text = f"{math.degrees(value):g} deg"
            elif UNITS.get(f.name) == "px":
                text = f"{value:g} px"
            else:
                text = f"{value:g}"
            rows.append((f.name, text, PROVENANCE[f.name]))
        return rows


def count(value, name: str) -> int:
    """``value`` as a count in [1, :data:`MAX_COUNT`] (an int: no bool, no float, no string), or
    :class:`SimulationError` naming ``name``."""
    return integer(value, name, low=1, high=MAX_COUNT, error=SimulationError)


def generator(seed) -> np.random.Generator:
    """``np.random.default_rng(seed)`` for a seed that is an integer >= 0, else :class:`SimulationError`
    naming ``seed`` (numpy would take a string array or a list as entropy, or raise a bare TypeError)."""
    return np.random.default_rng(integer(seed, "seed", low=0, error=SimulationError))


def study_inputs(system, model, guidance=None, model_name: str = "model"):
    """``(system, model, guidance)`` of a study, each checked: a :class:`carmkin.CArmSystem`, an
    :class:`ErrorModel`, and None or a :class:`carmkin.reposition.guidance.GuidanceOptions`; else
    :class:`SimulationError` naming the argument (the model's: ``model_name``)."""
    from carmkin.model.system import require_system
    from carmkin.reposition.guidance import GuidanceOptions
    from carmkin.validation import instance

    require_system(system, SimulationError)
    instance(model, ErrorModel, model_name, error=SimulationError)
    if guidance is not None:
        instance(guidance, GuidanceOptions, "guidance", error=SimulationError)
    return system, model, guidance


def square_pixel_system(system):
    """``system`` with square detector pixels: width and image size kept, height = width · rows / columns."""
    carm = system.carm
    height = carm.detector_width * carm.detector_rows / carm.detector_columns
    return system.replace(carm=dataclasses.replace(carm, detector_height=height))


def format_model(model: ErrorModel) -> str:
    """The error model as a table: parameter, value, provenance."""
    lines = [f"{'parameter':<24}{'value':>12}  provenance"]
    lines += [f"{name:<24}{value:>12}  {why}" for name, value, why in model.table()]
    lines.append(f"{'thresholds':<24}{'2 mm, 0.5 deg':>12}  {PROVENANCE['thresholds']}")
    lines.append(f"{'square pixels':<24}{'0.2875 mm':>12}  {PROVENANCE['square pixels']}")
    return "\n".join(lines)
