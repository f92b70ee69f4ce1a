"""Calibration boards: the printed image (for the simulator), object points, and detection."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from rig.config import BoardConfig

WHITE, BLACK = 0.85, 0.05  # albedo of the printed board


@dataclass(frozen=True)
class Detection:
    """Corners found in one image: board corner ids and their sub-pixel image positions."""

    ids: np.ndarray  # (N,) int
    points: np.ndarray  # (N, 2) float64

    def __len__(self) -> int:
        return len(self.ids)


SUBPIXEL = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 0.001)


class Board:
    """Object points in the board frame: origin at the board's centre, x along the columns, y
    against the rows (up the printed page), z = x cross y out of the printed face. A board lying
    face up on the bench so has z up; the first view's board is the world frame."""

    def __init__(self, config: BoardConfig) -> None:
        self.config = config
        cols, rows = config.squares  # checked by BoardConfig; counts of one parity: orientation_warning
        self.inner = (cols - 1, rows - 1)
        sq = config.square_mm
        self.size_mm = (cols * sq + 2 * config.margin_mm, rows * sq + 2 * config.margin_mm)
        c, r = np.meshgrid(np.arange(1, cols), np.arange(1, rows))
        corners = np.column_stack([c.ravel() * sq, r.ravel() * sq]) + config.margin_mm
        centre = np.array(self.size_mm) / 2
        self._object = np.column_stack([corners[:, 0] - centre[0], centre[1] - corners[:, 1], np.zeros(len(corners))])
        if config.kind == "charuco":
            dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, config.dictionary))
            self._charuco = cv2.aruco.CharucoBoard((cols, rows), sq, config.marker_mm, dictionary)
            self._detector = cv2.aruco.CharucoDetector(self._charuco)

    def print_pose(self, rotation: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For a board frame at `rotation` (board -> world) about `centre`: the frame of its printed
        image (columns, rows, normal into the print) and the image's top-left corner in the world."""
        axes = np.column_stack([rotation[:, 0], -rotation[:, 1], -rotation[:, 2]])
        w, h = self.size_mm
        return axes, np.asarray(centre, float) - axes @ np.array([w / 2, h / 2, 0.0])

    @property
    def corner_count(self) -> int:
        return len(self._object)

    def object_points(self, ids: np.ndarray) -> np.ndarray:
        return self._object[ids]

    def image(self, px_per_mm: float = 10.0) -> np.ndarray:
        """The printed board as albedo (float32), top-left at the board's corner."""
        cfg = self.config
        cols, rows = cfg.squares
        w, h = (round(s * px_per_mm) for s in self.size_mm)
        margin = round(cfg.margin_mm * px_per_mm)
        inner_w, inner_h = w - 2 * margin, h - 2 * margin
        if cfg.kind == "checker":
            y, x = np.mgrid[0:inner_h, 0:inner_w]
            col = (x * cols) // inner_w
            row = (y * rows) // inner_h
            squares = np.where((col + row) % 2 == 0, BLACK, WHITE).astype(np.float32)
        else:
            printed = self._charuco.generateImage((inner_w, inner_h), marginSize=0, borderBits=1)
            squares = (BLACK + (WHITE - BLACK) * (printed.astype(np.float32) / 255.0)).astype(np.float32)
        out = np.full((h, w), WHITE, dtype=np.float32)
        out[margin : margin + inner_h, margin : margin + inner_w] = squares
        return out

    def detect(self, image: np.ndarray) -> Detection:
        """Corners in an 8-bit or 16-bit image (mono or BGR); empty when the board is not found."""
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        if gray.dtype != np.uint8:
            gray = cv2.normalize(gray, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
        if self.config.kind == "charuco":
            corners, ids, _, _ = self._detector.detectBoard(gray)
            if ids is None or len(ids) < 4:
                return Detection(np.zeros(0, int), np.zeros((0, 2)))
            # The detector's corners lean toward the markers; refined on the saddle itself, a
            # quarter-resolution camera's focal length came within 0.3 % (was up to 2 % long).
            refined = cv2.cornerSubPix(gray, corners.astype(np.float32), (2, 2), (-1, -1), SUBPIXEL)
            return Detection(ids.ravel().astype(int), refined.reshape(-1, 2).astype(np.float64))
        found, corners = cv2.findChessboardCornersSB(gray, self.inner, flags=cv2.CALIB_CB_ACCURACY)
        if not found:
            return Detection(np.zeros(0, int), np.zeros((0, 2)))
        points = corners.reshape(-1, 2).astype(np.float64)
        if not self._first_square_is_black(gray, points):
            points = points[::-1]  # OpenCV started from the other end: a 180 degree turn
        return Detection(np.arange(len(points)), points)

    def _first_square_is_black(self, gray: np.ndarray, points: np.ndarray) -> bool:
        """The board's first square (row 0, column 0) is black and its neighbours white: compare the
        square diagonally outward from corner 0 with the one beside it."""
        cols = self.inner[0]
        along_row = points[1] - points[0]
        along_col = points[cols] - points[0]

        def value(offset: np.ndarray) -> int:
            x, y = np.rint(points[0] + offset).astype(int)
            return int(gray[min(max(y, 0), gray.shape[0] - 1), min(max(x, 0), gray.shape[1] - 1)])

        return value(-0.5 * (along_row + along_col)) < value(0.5 * (along_col - along_row))
