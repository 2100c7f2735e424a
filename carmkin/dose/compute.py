"""The entrance skin dose of a procedure on skin cells.

For each event and each skin cell its beam enters (:mod:`carmkin.dose.skin`):

    D = K_IRP × (d_IRP / d)² × f × B × T

with d the source–cell distance and d_IRP the source–IRP distance (inverse square), f the air-to-water
conversion ``(μen/ρ)_water/(μen/ρ)_air`` and B the backscatter factor (:mod:`carmkin.dose.coefficients`, at
the event's kVp and HVL, B at the square-equivalent field side at the cell, f at the mean one), T the table
and pad transmission when the segment from the source to the cell crosses the table top (a box of the
system's ``table.top_size`` at ``table.top_center``), else 1. The map is the sum over events; the peak skin
dose (PSD) is its maximum cell and the overlap of a cell the number of events whose field enters it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.dose import coefficients
from carmkin.dose.event import Beam, Event, beam, field_side_cm
from carmkin.dose.skin import DEFAULT_SPACING, Skin, skin_of
from carmkin.errors import DoseError

#: A segment that ends within this (m) of the table top's surface does not cross the top (a cell resting on
#: it, seen from above).
TABLE_CONTACT = 1e-6


@dataclass(frozen=True)
class EventDose:
    """One event's part of the map: the cells it hits (indices), their dose (Gy) and its corrections."""

    name: str
    cells: np.ndarray
    dose_gy: np.ndarray
    inverse_square: np.ndarray
    backscatter: np.ndarray
    medium: float
    table: np.ndarray
    hvl_mm_al: float
    field_centre: np.ndarray | None


@dataclass(frozen=True)
class DoseMap:
    """Cumulative entrance skin dose: ``cells`` (N, 3) m and ``normals`` (N, 3) in the table frame, ``dose_gy``
    (N,), ``overlap`` (N,) the number of entrance fields on each cell, ``psd_gy`` and ``psd_point`` (3,) m,
    ``events`` (one :class:`EventDose` each); ``faces`` (F, 3) the triangles joining the cells when the skin is a
    surface (:func:`carmkin.dose.from_surface`), else None."""

    cells: np.ndarray
    normals: np.ndarray
    dose_gy: np.ndarray
    overlap: np.ndarray
    psd_gy: float
    psd_point: np.ndarray
    events: tuple
    faces: np.ndarray | None = None

    def shared_cells(self) -> np.ndarray:
        """(E, E) int: the number of skin cells the entrance fields of events i and j both cover (the diagonal:
        each event's own); times the cell area, the overlap of two fields on the skin."""
        hits = np.zeros((len(self.events), len(self.cells)), dtype=np.int64)
        for i, part in enumerate(self.events):
            hits[i, part.cells] = 1
        return hits @ hits.T

    def summary(self) -> dict:
        """Plain numbers (mm, Gy) for a report."""
        return {"psd_gy": self.psd_gy, "psd_point_mm": [round(float(v) * 1e3, 3) for v in self.psd_point],
                "cells": int(len(self.cells)), "events": len(self.events),
                "events_hitting_skin": sum(1 for e in self.events if len(e.cells)),
                "max_overlap": int(self.overlap.max(initial=0)),
                "cells_hit": int(np.count_nonzero(self.overlap))}


def crosses_box(source: np.ndarray, points: np.ndarray, center, size) -> np.ndarray:
    """(N,) bool: the segments from ``source`` to ``points`` (N, 3) pass through the axis-aligned box
    (table frame) of ``size`` at ``center`` — ending on its surface (within :data:`TABLE_CONTACT`) is not
    passing through."""
    lo = np.asarray(center) - np.asarray(size) / 2
    hi = np.asarray(center) + np.asarray(size) / 2
    d = points - source
    t_in = np.zeros(len(points))
    t_out = np.ones(len(points))
    length = np.linalg.norm(d, axis=1)
    for k in range(3):
        dk = d[:, k]
        flat = np.abs(dk) < 1e-15
        outside = flat & ((source[k] < lo[k]) | (source[k] > hi[k]))
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = np.where(flat, -np.inf, (lo[k] - source[k]) / np.where(flat, 1.0, dk))
            t2 = np.where(flat, np.inf, (hi[k] - source[k]) / np.where(flat, 1.0, dk))
        t_in = np.maximum(t_in, np.minimum(t1, t2))
        t_out = np.minimum(t_out, np.maximum(t1, t2))
        t_out = np.where(outside, -1.0, t_out)
    margin = TABLE_CONTACT / np.maximum(length, 1e-30)
    return (t_out - t_in > margin) & (t_in < 1.0 - margin)


def _hvl(event: Event) -> float:
    if event.hvl_mm_al is not None:
        return event.hvl_mm_al
    return coefficients.half_value_layer(event.kvp, event.filter["Cu"], event.filter["Al"])


def event_dose(system, event: Event, skin: Skin, columns: np.ndarray | None = None) -> EventDose:
    """The dose (Gy) one event gives the cells its beam enters (``columns``: ``skin.points.T``, contiguous)."""
    b: Beam = beam(system, event)
    hit = np.flatnonzero(b.inside(skin.points) if columns is None else b.inside_columns(columns))
    if not skin.two_sided:  # entrance cells: facing the source
        hit = hit[np.einsum("ij,ij->i", skin.normals[hit], skin.points[hit] - b.source) < 0.0]
    hvl = _hvl(event)
    if not len(hit):
        empty = np.zeros(0)
        return EventDose(event.name, hit, empty, empty, empty, 1.0, empty, hvl, None)
    d = np.linalg.norm(skin.points[hit] - b.source, axis=1)
    k_isq = (b.d_irp / d) ** 2
    side = field_side_cm(b, d)
    try:
        k_bs = coefficients.backscatter(event.kvp, hvl, side)
        k_med = coefficients.medium_factor(event.kvp, hvl, float(np.mean(side)))
    except DoseError as exc:
        raise DoseError(f"{event._label}{exc}") from None
    t = coefficients.DEFAULT_TABLE_TRANSMISSION if event.table_transmission is None else event.table_transmission
    crosses = crosses_box(b.source, skin.points[hit], system.table.top_center, system.table.top_size)
    k_tab = np.where(crosses, t, 1.0)
    dose = event.k_irp_gy * k_isq * k_med * k_bs * k_tab
    # the field centre on the skin: the hit cell nearest the principal axis
    off_axis = np.linalg.norm(np.cross(skin.points[hit] - b.source, b.axis), axis=1)
    return EventDose(event.name, hit, dose, k_isq, k_bs, k_med, k_tab, hvl, skin.points[hit][np.argmin(off_axis)])


def _check_events(events) -> list:
    if isinstance(events, (str, bytes, Event)) or not hasattr(events, "__iter__"):
        raise DoseError(f"events must be a sequence of carmkin.dose.Event, got {type(events).__name__}")
    events = list(events)
    if not events:
        raise DoseError("events must hold at least one carmkin.dose.Event, got none")
    for i, e in enumerate(events):
        if not isinstance(e, Event):
            raise DoseError(f"events[{i}] must be a carmkin.dose.Event, got {type(e).__name__}")
    return events


def skin_dose(system, events, patient, *, spacing: float = DEFAULT_SPACING) -> DoseMap:
    """The cumulative entrance skin dose of ``events`` (a sequence of :class:`Event`) on ``system`` for
    ``patient`` (a :class:`carmkin.patient.ParametricPatient` resting on the system's table top, else
    :class:`~carmkin.errors.PatientModelError`, sampled at ``spacing`` m; or skin cells from
    :func:`carmkin.dose.skin.plane` / :func:`~carmkin.dose.skin.cylinder`)."""
    from carmkin.model.system import require_system

    require_system(system, DoseError)
    events = _check_events(events)
    return planes_dose([(system, e) for e in events], patient, spacing=spacing)


def planes_dose(pairs, patient, *, spacing: float = DEFAULT_SPACING) -> DoseMap:
    """:func:`skin_dose` of events each on its own system: ``pairs`` a sequence of (system, :class:`Event`), the
    systems sharing one table (a biplane's two planes); the map is the sum over the events, in their order."""
    pairs = list(pairs)
    _check_events([e for _, e in pairs])
    from carmkin.patient import ParametricPatient

    if isinstance(patient, ParametricPatient):
        for system in {id(s): s for s, _ in pairs}.values():
            patient.check_placement(system, "patient")  # it must rest on this system's table top
    skin = skin_of(patient, spacing)
    dose = np.zeros(len(skin.points))
    overlap = np.zeros(len(skin.points), dtype=int)
    parts = []
    columns = np.ascontiguousarray(skin.points.T)
    for system, e in pairs:
        part = event_dose(system, e, skin, columns)
        dose[part.cells] += part.dose_gy
        overlap[part.cells] += 1
        parts.append(part)
    peak = int(np.argmax(dose))
    return DoseMap(skin.points, skin.normals, dose, overlap, float(dose[peak]), skin.points[peak].copy(), tuple(parts),
                   skin.faces)
