"""PointSet: the points of a scan with their attributes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class PointSet:
    """N points in the world frame (mm) with unit normals, colour, quality and provenance.

    `source` is the (projector, camera) pair index, `pixel` the flat camera pixel index the point
    came from (row * width + column) or -1, `angle` the triangulation angle in degrees (NaN where
    not known).

    Points are float32, as a scan stores them (cloud.ply): 1.2e-4 mm steps 2 m from the origin,
    a four-hundredth of the bench's accuracy, for half the memory of float64 (13 MB of a
    default scan's 61). Arrays of other types are converted on the way in.
    """

    FIELDS = ("points", "normals", "colors", "quality", "source", "pixel", "angle")

    points: np.ndarray  # (N, 3) float32
    normals: np.ndarray  # (N, 3) float32
    colors: np.ndarray  # (N, 3) uint8 RGB
    quality: np.ndarray  # (N,) float32
    source: np.ndarray  # (N,) uint8
    pixel: np.ndarray  # (N,) int32
    angle: np.ndarray | None = None  # (N,) float32; None: not known (NaN in files)

    def __post_init__(self) -> None:
        for name, dtype in (("points", np.float32), ("pixel", np.int32)):
            object.__setattr__(self, name, np.asarray(getattr(self, name)).astype(dtype, copy=False))
        if self.angle is None:  # a read-only view of one NaN, not an array of the cloud's length
            object.__setattr__(self, "angle", np.broadcast_to(np.float32(np.nan), (len(self.points),)))

    def __len__(self) -> int:
        return len(self.points)

    @staticmethod
    def empty() -> PointSet:
        return PointSet(
            np.zeros((0, 3), np.float32),
            np.zeros((0, 3), np.float32),
            np.zeros((0, 3), np.uint8),
            np.zeros(0, np.float32),
            np.zeros(0, np.uint8),
            np.zeros(0, np.int32),
            np.zeros(0, np.float32),
        )

    @staticmethod
    def concatenate(sets: list[PointSet]) -> PointSet:
        """The sets one after another (a single set is returned itself, not copied)."""
        if not sets:
            return PointSet.empty()
        if len(sets) == 1:
            return sets[0]
        return PointSet(*(np.concatenate([getattr(s, f) for s in sets]) for f in PointSet.FIELDS))
