"""Named standard views as data: XA primary / secondary angles (deg; PS3.3 C.8.7.5.1.2: the direction from the
isocentre to the detector, primary LAO +, secondary CRA +) with the source of each angle.

A C-arm images along a line: a beam from A to B and one from B to A give mirrored images of the same
projection. The angles below put the detector where a mobile C-arm with the tube under the table puts it
(anterior for a supine patient), so the "AP" view is primary 0°, secondary 0°.
"""

from __future__ import annotations

from dataclasses import dataclass

from carmkin.errors import ViewError


@dataclass(frozen=True)
class StandardView:
    """``primary_deg`` (LAO +), ``secondary_deg`` (CRA +), what it shows and the source of its angles."""

    name: str
    primary_deg: float
    secondary_deg: float
    description: str
    source: str


_PENNAL = "Pennal GF, Tile M, Waddell JP, Garside H. Pelvic disruption. Clin Orthop 1980;151:12-21 (40° tilts)"
_JUDET = "Judet R, Judet J, Letournel E. Fractures of the acetabulum. J Bone Joint Surg Am 1964;46:1615-46 (45°)"
#: Every coronary view's angles lie inside the ranges of Table 2 of this source (its projection, LAO/RAO and
#: cranial/caudal ranges quoted in the description; the value is the range's middle or a round value in it).
_CORONARY = ("Di Mario C, Sutaria N. Coronary angiography in the angioplasty era: projections with a meaning. "
             "Heart 2005;91:968-76, Table 2")
_DICOM = "DICOM PS3.3 C.8.7.5.1.2 (primary 0° = detector perpendicular to the chest, +90° = patient's left)"

STANDARD_VIEWS: dict[str, StandardView] = {v.name: v for v in (
    StandardView("ap", 0.0, 0.0, "frontal, detector anterior", _DICOM),
    StandardView("pa", 180.0, 0.0, "frontal, detector posterior", _DICOM),
    StandardView("lateral-left", 90.0, 0.0, "lateral, detector at the patient's left", _DICOM),
    StandardView("lateral-right", -90.0, 0.0, "lateral, detector at the patient's right", _DICOM),
    StandardView("lao-30", 30.0, 0.0, "left anterior oblique 30°", _DICOM),
    StandardView("rao-30", -30.0, 0.0, "right anterior oblique 30° (RCA: RAO 30–45°, Table 2)", _CORONARY),
    StandardView("lao-50", 50.0, 0.0, "left anterior oblique 50° (RCA: LAO 45–60°, Table 2)", _CORONARY),
    StandardView("lao-40-cranial-30", 40.0, 30.0, "LAO cranial (LAD, diagonals: LAO 30–45°, cranial 25–35°, "
                 "Table 2)", _CORONARY),
    StandardView("lao-45-caudal-30", 45.0, -30.0, "LAO caudal, the 'spider' (LM bifurcation, proximal LCx: "
                 "LAO 40–50°, caudal 25–40°, Table 2)", _CORONARY),
    StandardView("rao-35-caudal-35", -35.0, -35.0, "RAO caudal (LCx, OM, proximal LAD: RAO 30–45°, caudal "
                 "30–40°, Table 2)", _CORONARY),
    StandardView("rao-10-cranial-40", -10.0, 40.0, "AP/RAO cranial (mid and distal LAD: AP/RAO 5–10°, cranial "
                 "35–45°, Table 2)", _CORONARY),
    StandardView("rao-10-caudal-30", -10.0, -30.0, "AP/RAO caudal (LM, proximal LAD and LCx: AP/RAO 5–15°, "
                 "caudal 30°, Table 2)", _CORONARY),
    StandardView("pelvis-inlet", 0.0, 40.0,
                 "pelvic inlet: the axis from anterior-cranial to posterior-caudal, 40° from frontal", _PENNAL),
    StandardView("pelvis-outlet", 0.0, -40.0,
                 "pelvic outlet: the axis from anterior-caudal to posterior-cranial, 40° from frontal", _PENNAL),
    StandardView("judet-lao-45", 45.0, 0.0, "Judet oblique 45° to the left (obturator oblique of the left "
                 "acetabulum, iliac oblique of the right)", _JUDET),
    StandardView("judet-rao-45", -45.0, 0.0, "Judet oblique 45° to the right (obturator oblique of the right "
                 "acetabulum, iliac oblique of the left)", _JUDET),
)}


def standard_view(name: str, target=(0.0, 0.0, 0.0), position="HFS"):
    """The :class:`~carmkin.views.View` of a named standard view through ``target`` (m, table frame) for a
    patient in ``position`` (code, LPS pose or patient model)."""
    from .view import View

    key = str(name).lower()
    if key not in STANDARD_VIEWS:
        raise ViewError(f"unknown standard view {name!r}; known: {', '.join(STANDARD_VIEWS)}")
    v = STANDARD_VIEWS[key]
    return View.from_angles(v.primary_deg, v.secondary_deg, target, position, name=key)
