"""One irradiation event and its beam in the table frame: source, principal axis, collimated field, IRP.

The geometry comes from the joints: ``system.fk(q)`` is the X-ray source frame (Z along the principal axis,
towards the detector; X, Y along the image width and height). The isocentre lies on the principal axis at
the preset's source–isocentre distance (``system.carm.orbital_offset``); an event may state its own
source–isocentre distance (a report's Distance Source to Isocenter), which moves the source along the axis
with the isocentre kept. The interventional reference point (IRP) is :data:`IRP_FROM_ISOCENTRE` from the
isocentre towards the source (IEC 60601-2-43 201.3.214). The collimated field is a rectangle
``field_mm = (w, h)`` (mm along the image X and Y) at the detector, the source–detector distance of the event
or of the preset: the beam is the pyramid from the source through it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from carmkin.errors import DoseError
from carmkin.validation import real_array, real_scalar

#: Distance (m) of the interventional reference point from the isocentre towards the source.
# source: IEC 60601-2-43:2010 201.3.214 (15 cm from the isocentre towards the focal spot); PySkinDose DSIRP = DSI - 15 cm
IRP_FROM_ISOCENTRE = 0.15
#: Largest air kerma (Gy) one event may state: a guard against a unit slip (mGy or µGy given as Gy).
MAX_KERMA_GY = 100.0
#: Added filter materials an event may name (mm of each).
FILTER_MATERIALS = ("Cu", "Al")


@dataclass(frozen=True)
class Event:
    """An irradiation event: joints ``q`` (the system's order, m and rad), tube voltage ``kvp`` (kV), air kerma
    at the IRP ``k_irp_gy`` (Gy), collimated field ``field_mm = (w, h)`` at the detector (mm along the image X
    and Y), added ``filter`` as ``{"Cu": mm, "Al": mm}``; optional: ``hvl_mm_al`` (else from the HVL table),
    ``table_transmission`` (else :data:`carmkin.dose.coefficients.DEFAULT_TABLE_TRANSMISSION`),
    ``source_to_isocenter_mm`` / ``source_to_detector_mm`` (else the preset's), ``name``."""

    q: tuple
    kvp: float
    k_irp_gy: float
    field_mm: tuple[float, float]
    filter: dict = field(default_factory=dict)
    hvl_mm_al: float | None = None
    table_transmission: float | None = None
    source_to_isocenter_mm: float | None = None
    source_to_detector_mm: float | None = None
    name: str = ""

    def __post_init__(self) -> None:
        from carmkin.dose.coefficients import check_kvp

        q = real_array(self.q, f"{self._label}q", (None,), error=DoseError, unit="m, rad")
        object.__setattr__(self, "q", tuple(float(v) for v in q))
        object.__setattr__(self, "kvp", check_kvp(self.kvp, f"{self._label}kvp"))
        object.__setattr__(self, "k_irp_gy", real_scalar(self.k_irp_gy, f"{self._label}k_irp_gy", error=DoseError,
                                                         low=0.0, high=MAX_KERMA_GY, unit="Gy"))
        size = real_array(self.field_mm, f"{self._label}field_mm", (2,), error=DoseError, unit="mm")
        if np.any(size <= 0.0):
            raise DoseError(f"{self._label}field_mm must be two positive sides (w, h) in mm at the detector, got "
                            f"{tuple(size.tolist())}")
        object.__setattr__(self, "field_mm", (float(size[0]), float(size[1])))
        if not isinstance(self.filter, dict) or set(self.filter) - set(FILTER_MATERIALS):
            raise DoseError(f"{self._label}filter must be a dict of mm per material {FILTER_MATERIALS}, got "
                            f"{self.filter!r:.80}")
        object.__setattr__(self, "filter", {m: real_scalar(self.filter.get(m, 0.0), f"{self._label}filter {m}",
                                                           error=DoseError, low=0.0, high=10.0, unit="mm")
                                            for m in FILTER_MATERIALS})
        if self.hvl_mm_al is not None:
            object.__setattr__(self, "hvl_mm_al", real_scalar(self.hvl_mm_al, f"{self._label}hvl_mm_al",
                                                              error=DoseError, low=0.5, high=20.0, unit="mm Al"))
        if self.table_transmission is not None:
            t = real_scalar(self.table_transmission, f"{self._label}table_transmission", error=DoseError,
                            low=0.0, high=1.0)
            if t == 0.0:
                raise DoseError(f"{self._label}table_transmission must be in (0, 1], got 0")
            object.__setattr__(self, "table_transmission", t)
        for name in ("source_to_isocenter_mm", "source_to_detector_mm"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, real_scalar(getattr(self, name), f"{self._label}{name}",
                                                           error=DoseError, low=200.0, high=3000.0, unit="mm"))
        if not isinstance(self.name, str):
            raise DoseError(f"Event name must be a string, got {self.name!r:.60}")

    @property
    def _label(self) -> str:
        name = self.__dict__.get("name")
        return f"event {name!r}: " if isinstance(name, str) and name else ""


@dataclass(frozen=True)
class Beam:
    """An event's beam in the table frame (m): ``source`` (3,), unit ``axis`` (principal axis, towards the
    detector), unit ``u``, ``v`` (image X and Y), ``half_tan`` (2,) the tangents of the field's half angles
    along u and v, ``irp`` (3,) and ``d_irp`` (m, source to IRP), ``sid`` (m, source to detector),
    ``field_area_m2`` at the detector."""

    source: np.ndarray
    axis: np.ndarray
    u: np.ndarray
    v: np.ndarray
    half_tan: np.ndarray
    irp: np.ndarray
    d_irp: float
    sid: float
    field_area_m2: float

    def inside(self, points: np.ndarray) -> np.ndarray:
        """(N,) bool: the points (N, 3) inside the beam's pyramid (its faces included), beyond the source."""
        return self.inside_columns(np.ascontiguousarray(np.asarray(points, float).T))

    def inside_columns(self, columns: np.ndarray) -> np.ndarray:
        """:meth:`inside` for the points given as their three coordinate rows (3, N)."""
        x, y, z = (columns[k] - self.source[k] for k in range(3))

        def along(e):  # elementwise (no BLAS call: a skinny product threads badly on a loaded machine)
            return x * e[0] + y * e[1] + z * e[2]

        depth = along(self.axis)
        return ((depth > 0.0) & (np.abs(along(self.u)) <= depth * self.half_tan[0])
                & (np.abs(along(self.v)) <= depth * self.half_tan[1]))


def beam(system, event: Event) -> Beam:
    """The beam of ``event`` on ``system`` (table frame, m)."""
    if len(event.q) != system.nq:
        raise DoseError(f"{event._label}q must have the system's {system.nq} joints, got {len(event.q)}")
    T = system.fk(np.asarray(event.q))
    axis = T[:3, 2]
    isocentre = T[:3, 3] + system.carm.orbital_offset * axis
    dsi = system.carm.orbital_offset if event.source_to_isocenter_mm is None else event.source_to_isocenter_mm / 1e3
    sid = system.carm.source_to_detector if event.source_to_detector_mm is None else event.source_to_detector_mm / 1e3
    if dsi <= IRP_FROM_ISOCENTRE or sid <= dsi:
        raise DoseError(f"{event._label}the source-isocentre distance {dsi * 1e3:g} mm must exceed the IRP's "
                        f"{IRP_FROM_ISOCENTRE * 1e3:g} mm and be less than the source-detector distance {sid * 1e3:g} mm")
    source = isocentre - dsi * axis
    w, h = (s / 1e3 for s in event.field_mm)
    return Beam(source=source, axis=axis, u=T[:3, 0], v=T[:3, 1], half_tan=np.array([w / 2 / sid, h / 2 / sid]),
                irp=isocentre - IRP_FROM_ISOCENTRE * axis, d_irp=dsi - IRP_FROM_ISOCENTRE, sid=sid,
                field_area_m2=w * h)


def field_side_cm(b: Beam, distance: np.ndarray) -> np.ndarray:
    """Square-equivalent field side (cm) at ``distance`` (m) from the source: √area scaled by distance / SID
    (PySkinDose's ``scale_field_area``)."""
    return math.sqrt(b.field_area_m2) * 100.0 * np.asarray(distance) / b.sid
