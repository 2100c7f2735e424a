"""Certified contact regions: one exact contact proves its neighbours of the same view touch too.

For a view, everything the orbital joint carries (source housing, detector, C-arc) is one rigid body whose
pose is set by the source–target distance s and the roll ρ about the beam alone: a point of it at distance r
from the beam axis moves by at most ``|Δs| + r |Δρ|``. The signed distance of two convex shapes changes no
faster than their points move (both ways: it is a difference of support functions, each 1-Lipschitz in the
Hausdorff distance). So a candidate (s_c, ρ_c) whose pair k — such a part against a convex body fixed to
the table frame — is at d_k < margin (coal) keeps that pair closer than the margin wherever

    |s − s_c| + r_k |ρ − ρ_c| < margin − d_k − accuracy(d_k),

r_k the largest distance of the moving shape from the beam axis (:attr:`carmkin.world.beam.BeamScreen.roll_lever`),
accuracy coal's (:func:`carmkin.world.tolerances.accuracy`). A candidate there is not checked: it touches. Candidates of the
contact cells of a map lie mostly in such regions, so a few exact checks decide a cell.
Written here: no library bounds a distance over a family of rigid motions this way.
"""

from __future__ import annotations

import numpy as np

from carmkin.world.tolerances import accuracy


class Regions:
    """The regions of every cell of a search: ``cell`` (R,), ``where`` (R, 2) their (s_c, ρ_c) (m, rad),
    ``lever`` (R,) r_k (m), ``slack`` (R,) the right-hand side above (m)."""

    def __init__(self, world, margin: float) -> None:
        self.world, self.margin = world, margin
        self.cell = np.zeros(0, dtype=int)
        self.where = np.zeros((0, 2))
        self.lever = np.zeros(0)
        self.slack = np.zeros(0)
        self._order = None  # the regions sorted by cell, until the next add

    def add(self, cells, where, distances, pairs) -> None:
        """Regions about candidates (s, ρ) ``where`` (M, 2) of ``cells`` (M,) whose pairs ``pairs`` (M,) are at
        ``distances`` (M,) (m) below the margin; pairs that are not rigid with the source are skipped."""
        lever = self.world.beam.roll_lever[np.maximum(pairs, 0)]
        keep = (pairs >= 0) & np.isfinite(lever) & (distances < self.margin)
        if not keep.any():
            return
        d = distances[keep]
        self.cell = np.r_[self.cell, cells[keep]]
        self.where = np.vstack((self.where, where[keep]))
        self.lever = np.r_[self.lever, lever[keep]]
        self.slack = np.r_[self.slack, self.margin - d - accuracy(d)]
        self._order = None

    def contain(self, cells, where) -> np.ndarray:
        """(M,) True where candidate (s, ρ) ``where[m]`` lies in a region of cell ``cells[m]``."""
        out = np.zeros(len(cells), dtype=bool)
        if not len(self.cell) or not len(cells):
            return out
        if self._order is None:
            self._order = np.argsort(self.cell, kind="stable")
        order = self._order
        sorted_cells = self.cell[order]
        start = np.searchsorted(sorted_cells, cells, "left")
        count = np.searchsorted(sorted_cells, cells, "right") - start
        total = int(count.sum())
        if not total:
            return out
        # Every (candidate, region of its cell) pair, flattened.
        row = np.repeat(np.arange(len(cells)), count)
        region = order[np.arange(total) - np.repeat(np.cumsum(count) - count, count) + np.repeat(start, count)]
        delta = np.abs(where[row] - self.where[region])
        delta[:, 1] = np.minimum(delta[:, 1], 2 * np.pi - delta[:, 1])  # roll difference, wrapped
        reach = delta[:, 0] + self.lever[region] * delta[:, 1]
        out[row[reach < self.slack[region]]] = True
        return out
