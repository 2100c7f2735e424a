"""The planar marker pattern under the table (§3.3.1, Fig. 3.2) and how it is mounted.

The seed's pattern is a grid of uniquely detectable square markers, 16.5 mm squares 5.5 mm apart; its
modern, detectable equivalent is an OpenCV ArUco grid board (:class:`cv2.aruco.GridBoard`) with the same
square size and gap. Marker frame (OpenCV's board frame): origin at the outer corner of marker 0,
X along the rows (the pattern's long edge), Y along the columns, Z = X × Y pointing *away* from the printed
side, i.e. into the table when the printed side faces the camera below it. Lengths in metres.

The pattern is fixed under the table with an unknown rotation ``tRm`` (calibrated by :mod:`.calibration`);
its origin in the table frame 0 is a known mounting offset. The seed defines the table frame's origin at the
marker origin (offset 0); carmkin keeps the preset's table frame (origin at the isocentre at rest, Y0 down),
so the board's origin sits at a stated offset in it. Only poses relative to the table matter for
repositioning, so the choice of origin does not change any error.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from carmkin.errors import (
    PatternError,  # noqa: F401 (defined there, raised here)
)
from carmkin.extras import require
from carmkin.transforms import check_rigid_transform
from carmkin.validation import distance, real_scalar, rotation

#: Square size and gap of the seed's pattern (Fig. 3.2 caption), m.
SEED_MARKER_LENGTH = 0.0165
SEED_MARKER_SEPARATION = 0.0055


@dataclass(frozen=True)
class MarkerBoard:
    """An ArUco grid board: ``columns`` × ``rows`` markers of ``marker_length`` with ``separation`` (m).

    Default: 45 × 22 markers of the seed's size (0.98 m × 0.48 m), 990 of the 1000 ids of
    ``DICT_4X4_1000``, enough to stay in view over the table's translation range at the working distance.
    """

    columns: int = 45
    rows: int = 22
    marker_length: float = SEED_MARKER_LENGTH
    separation: float = SEED_MARKER_SEPARATION
    dictionary: str = "DICT_4X4_1000"

    def __post_init__(self) -> None:
        for name in ("columns", "rows"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise PatternError(f"MarkerBoard.{name} must be a positive integer, got {value!r}")
        for name in ("marker_length", "separation"):
            distance(getattr(self, name), f"MarkerBoard.{name}", error=PatternError)
        if not isinstance(self.dictionary, str) or not self.dictionary.startswith("DICT_"):
            raise PatternError(f"MarkerBoard.dictionary must name an ArUco dictionary (DICT_...), got {self.dictionary!r}")

    @property
    def pitch(self) -> float:
        """Distance between the corners of neighbouring markers (m)."""
        return self.marker_length + self.separation

    @property
    def size(self) -> tuple[float, float]:
        """Extent of the board along its X and Y (m)."""
        return (self.columns * self.pitch - self.separation, self.rows * self.pitch - self.separation)

    @cached_property
    def cv2_board(self):
        """The :class:`cv2.aruco.GridBoard` (OpenCV imported here, on first use)."""
        cv2 = require("cv2", "reposition")

        try:
            dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        except AttributeError as exc:
            raise PatternError(f"unknown ArUco dictionary {self.dictionary!r}") from exc
        if dictionary.bytesList.shape[0] < self.columns * self.rows:
            raise PatternError(f"{self.dictionary} has {dictionary.bytesList.shape[0]} markers, the board needs "
                               f"{self.columns * self.rows}")
        return cv2.aruco.GridBoard((self.columns, self.rows), self.marker_length, self.separation, dictionary)

    @cached_property
    def corners(self) -> np.ndarray:
        """Marker corners (n_markers, 4, 3) in the marker frame (m), in id order, OpenCV's corner order."""
        corners = np.array(self.cv2_board.getObjPoints(), dtype=float)
        corners.setflags(write=False)
        return corners


def nominal_mount(board: MarkerBoard, table_underside: float = 0.21) -> np.ndarray:
    """Pose (4, 4) of the marker frame in the table frame 0 for a board centred under the table.

    The preset's table frame has Z0 along the table translation, Y0 pointing down and the table top's
    underside at ``Y0 = table_underside`` (m; 0.21 m for the ``siremobile-iso-c3d`` table top). The board's
    X runs along Z0, its Z points up (−Y0) into the table, so its printed side faces the source below.
    """
    if not isinstance(board, MarkerBoard):
        raise PatternError(f"board must be a MarkerBoard, got {type(board).__name__}")
    table_underside = real_scalar(table_underside, "table_underside", error=PatternError, unit="m")
    R = np.column_stack(((0.0, 0.0, 1.0), (-1.0, 0.0, 0.0), (0.0, -1.0, 0.0)))
    width, height = board.size
    centre = np.array([0.0, table_underside, 0.0])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = centre - R @ np.array([width / 2, height / 2, 0.0])
    return T


def mounted(T_table_marker_nominal, rotation_error) -> np.ndarray:
    """The mount with its rotation perturbed by ``rotation_error`` (3, 3), about the marker origin."""
    T = check_rigid_transform(T_table_marker_nominal, "T_table_marker_nominal").copy()
    T[:3, :3] = T[:3, :3] @ rotation(rotation_error, "rotation_error", error=PatternError)
    return check_rigid_transform(T, "mounted pattern")
