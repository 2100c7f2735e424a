"""The one reader of the DICOM attributes that carry geometry (pydicom, the ``dicom`` extra).

Every number a reader of :mod:`carmkin.interop.dicom_io` takes from a dataset goes through
:func:`read_number`, the Patient Position through :func:`read_patient_position`, a functional group's item
through :func:`sequence_item`. Each checks, in this order: the attribute is present and not empty; it holds
one value (no multi-value, no sequence); the value is a number (pydicom's DS/IS/FL/FD types — never a string
parsed here, never a bool); it is finite; it lies within the standard's range (:data:`ATTRIBUTES`). Anything
else is a :class:`carmkin.errors.DicomAttributeError` whose message names the keyword and the tag, e.g.
``DistanceSourceToIsocenter (0018,9402) must be > 0 mm, got -1250``. Warnings pydicom raises while
converting a value (an invalid DS string) are caught: the value is then refused by type, never used.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

from carmkin.errors import DicomAttributeError, DicomGeometryError
from carmkin.interop import dicom
from carmkin.validation import _describe


@dataclass(frozen=True)
class Attribute:
    """A numeric geometry attribute: its unit and valid range (``positive``: strictly above ``low``)."""

    keyword: str
    unit: str
    low: float
    high: float
    positive: bool = False


_MM = dicom.MAX_DISTANCE_MM
#: The numeric attributes read, with their ranges: angles from PS3.3 C.8.7.5.1.2 (XA primary −180…180,
#: secondary −90…90) and C.8.19.6.13.1.2 (Ap1 −180…180, Ap2 −90…90), the detector rotation and table angles
#: over their decomposition ranges (see :mod:`carmkin.interop.dicom`); distances strictly positive (a negative
#: DistanceSourceToIsocenter would put the source on the detector's side) and, like table positions, within
#: :data:`carmkin.interop.dicom.MAX_DISTANCE_MM`.
ATTRIBUTES: dict[str, Attribute] = {a.keyword: a for a in (
    Attribute("PositionerPrimaryAngle", "deg", *dicom.PRIMARY_RANGE),
    Attribute("PositionerSecondaryAngle", "deg", *dicom.SECONDARY_RANGE),
    Attribute("PositionerIsocenterPrimaryAngle", "deg", *dicom.PRIMARY_RANGE),
    Attribute("PositionerIsocenterSecondaryAngle", "deg", *dicom.SECONDARY_RANGE),
    Attribute("PositionerIsocenterDetectorRotationAngle", "deg", *dicom.ROTATION_RANGE),
    Attribute("TableXPositionToIsocenter", "mm", -_MM, _MM),
    Attribute("TableYPositionToIsocenter", "mm", -_MM, _MM),
    Attribute("TableZPositionToIsocenter", "mm", -_MM, _MM),
    Attribute("TableHorizontalRotationAngle", "deg", *dicom.ROTATION_RANGE),
    Attribute("TableHeadTiltAngle", "deg", *dicom.HEAD_TILT_RANGE),
    Attribute("TableCradleTiltAngle", "deg", *dicom.ROTATION_RANGE),
    Attribute("DistanceSourceToIsocenter", "mm", 0.0, _MM, positive=True),
    Attribute("DistanceSourceToPatient", "mm", 0.0, _MM, positive=True),
    Attribute("DistanceSourceToDetector", "mm", 0.0, _MM, positive=True),
)}


def tag_text(keyword: str) -> str:
    """``"(gggg,eeee)"`` of a keyword, from pydicom's data dictionary."""
    if not isinstance(keyword, str):
        raise DicomGeometryError(f"keyword must be a DICOM keyword (str), got {_describe(keyword)}")
    try:
        from pydicom.datadict import tag_for_keyword
    except ImportError:  # pragma: no cover - without the dicom extra no dataset reaches here
        return "(?)"
    tag = tag_for_keyword(keyword)
    return "(?)" if tag is None else f"({tag >> 16:04X},{tag & 0xFFFF:04X})"


def _error(keyword: str, text: str) -> DicomAttributeError:
    tag = tag_text(keyword)
    return DicomAttributeError(f"{keyword} {tag} {text}", keyword, tag)


def check_dataset(ds, name: str = "ds"):
    """``ds`` if it is a pydicom Dataset (a functional group item included), else :class:`DicomGeometryError`."""
    try:
        from pydicom.dataset import Dataset
    except ImportError:  # pragma: no cover - without the dicom extra nothing is a Dataset
        Dataset = ()
    if not isinstance(ds, Dataset):
        raise DicomGeometryError(f"{name} must be a pydicom Dataset (pydicom.dcmread), got {_describe(ds)}")
    return ds


def _value(ds, keyword: str):
    """The attribute's value, or ``None`` when absent; conversion errors and warnings become typed errors."""
    if keyword not in ds:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an invalid value is refused below, by type
        try:
            return ds[keyword].value
        except Exception as exc:  # pydicom's conversion of a malformed value: any error type
            raise _error(keyword, f"cannot be read: {type(exc).__name__}: {exc}") from None


def read_number(ds, keyword: str) -> float:
    """The value of a numeric attribute of :data:`ATTRIBUTES` (deg or mm), checked (module docstring)."""
    check_dataset(ds)
    if not isinstance(keyword, str) or keyword not in ATTRIBUTES:
        raise DicomGeometryError(f"keyword must be one of {', '.join(ATTRIBUTES)}, got {_describe(keyword)}")
    spec = ATTRIBUTES[keyword]
    value = _value(ds, keyword)
    if value is None and keyword not in ds:
        raise _error(keyword, "is required, the dataset has none")
    if value is None or (isinstance(value, (str, bytes, list, tuple)) and len(value) == 0):
        raise _error(keyword, "is required, it is empty")
    if isinstance(value, (list, tuple)) or type(value).__name__ in ("MultiValue", "Sequence"):
        raise _error(keyword, f"must hold one value, got {len(value)}: {_describe(value)}")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _error(keyword, f"must be a number ({spec.unit}), got {_describe(value)} ({type(value).__name__})")
    number = float(value)
    if not math.isfinite(number):
        raise _error(keyword, f"must be finite ({spec.unit}), got {number}")
    if spec.positive and not number > spec.low:
        raise _error(keyword, f"must be > 0 {spec.unit}, got {number:g}")
    if not spec.low <= number <= spec.high:
        raise _error(keyword, f"must be within [{spec.low:g}, {spec.high:g}] {spec.unit}, got {number:g}")
    return number


def read_patient_position(ds, patient_position: str | None = None) -> str:
    """Patient Position (0018,5100): one of HFS, HFP, HFDR, HFDL, FFS, FFP, FFDR, FFDL. Missing or empty:
    ``patient_position`` if the caller passes one (checked the same way), else :class:`DicomAttributeError` — a
    patient-based angle means nothing without it, and no position is assumed silently."""
    from carmkin.imaging.projection import PATIENT_POSITIONS

    keyword = "PatientPosition"
    value = _value(check_dataset(ds), keyword)
    if value is None or value == "":
        if patient_position is None:
            raise _error(keyword, "is required to place the patient (XA angles are patient-based) and the dataset "
                                  "has none; pass patient_position= (e.g. 'HFS') to assume one")
        value, keyword = patient_position, "patient_position"
    if not isinstance(value, str) or value.strip().upper() not in PATIENT_POSITIONS:
        text = f"must be one of {', '.join(PATIENT_POSITIONS)}, got {_describe(value)}"
        if keyword == "patient_position":
            raise DicomGeometryError(f"patient_position {text}")
        raise _error(keyword, text)
    return value.strip().upper()


def sequence_items(ds, keyword: str) -> list:
    """The items (Datasets) of sequence ``keyword`` in ``ds``; ``[]`` when absent or empty."""
    tag_text(keyword)  # a str keyword
    value = _value(check_dataset(ds), keyword)
    if value is None or (isinstance(value, (str, bytes)) and not value):
        return []
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise _error(keyword, f"must be a sequence, got {_describe(value)}")
    return [check_dataset(item, f"an item of {keyword} {tag_text(keyword)}") for item in value]


def sequence_item(groups, keyword: str):
    """The first item of sequence ``keyword`` in the first functional group (a Dataset) that has a non-empty
    one; :class:`DicomAttributeError` when none has."""
    for group in groups:
        items = sequence_items(group, keyword)
        if items:
            return items[0]
    raise _error(keyword, "is required (an Enhanced XA functional group), the dataset has none")
