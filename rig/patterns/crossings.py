"""Ring edges in a camera image: where the edge pattern less its inverse changes sign between
neighbouring pixels (rig.patterns.rings). Found in two steps, so that a stream can look for them
as soon as the edge pair arrives: every sign change first (`Crossings.candidates`), then those
whose two pixels read the same ring index (`within_zones`), once the index code has come."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from rig.lazy import lazy_module

ring_kernels = lazy_module("rig.kernels.rings")  # numba compiles on first use


@dataclass(frozen=True, eq=False)
class Crossings:
    """Sign changes of pattern - inverse between neighbouring camera pixels a and b (index arrays),
    a fraction `t` of the way from a to b, with the step d(a) - d(b) and (once read) the ring index."""

    a: tuple[np.ndarray, np.ndarray]
    b: tuple[np.ndarray, np.ndarray]
    t: np.ndarray
    step: np.ndarray
    ring: np.ndarray | None = None

    @classmethod
    def candidates(cls, edge: np.ndarray, min_contrast: float) -> Crossings:
        """Every sign change of `edge` (float32) stepping by at least `min_contrast`, in row-major
        order of a, vertical neighbours first; each from the pair of neighbours across the edge
        (where the edge's slope across it is the steeper), a sign change counting 0 as positive: a
        pixel exactly on the ring (common in 8-bit captures) still yields its crossing, and each
        crossing is found once. One compiled pass to count them and one to list them
        (rig.kernels.rings.edge_crossings): numpy's passes held some 25 MB of images at 1280x1024."""
        if min(edge.shape) < 2:
            raise ValueError(f"an edge image of {edge.shape} pixels has no neighbours to cross between")
        image = np.ascontiguousarray(edge, np.float32)
        rows, cols, t, step, vertical = ring_kernels.edge_crossings(image, np.float32(min_contrast))
        down = np.zeros(len(rows), np.int64)
        down[:vertical] = 1  # b: the pixel below a, then the one to its right
        return cls((rows, cols), (rows + down, cols + (1 - down)), t, step)

    def within_zones(self, zone: np.ndarray, zone_ok: np.ndarray) -> Crossings:
        """The crossings whose two pixels read the same ring index, both readable (`zone_ok`)."""
        keep = zone_ok[self.a] & zone_ok[self.b] & (zone[self.a] == zone[self.b])
        return dataclasses.replace(self.select(keep), ring=zone[self.a][keep].astype(np.int64))

    @property
    def xy(self) -> np.ndarray:
        """Sub-pixel camera positions (M, 2): x, y."""
        return np.column_stack(
            [self.a[1] + self.t * (self.b[1] - self.a[1]), self.a[0] + self.t * (self.b[0] - self.a[0])]
        )

    def between(self, *images: np.ndarray) -> tuple[np.ndarray, ...]:
        """Each image interpolated at the crossings."""
        return self.interpolate(*((image[self.a], image[self.b]) for image in images))

    def interpolate(self, *at_ends: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, ...]:
        """Values given at each crossing's two pixels (a, b), interpolated at the crossing."""
        return tuple((1 - self.t) * at_a + self.t * at_b for at_a, at_b in at_ends)

    def ramp(self, edge: np.ndarray, contrast: np.ndarray) -> np.ndarray:
        """Half the step across each crossing of the edge pattern as a fraction of the white - black
        `contrast` there (in [-1, 1] on each side)."""
        a, b = (edge[end] / np.maximum(contrast[end], 1e-6) for end in (self.a, self.b))
        return 0.5 * np.abs(a - b)

    def select(self, keep: np.ndarray) -> Crossings:
        return Crossings(
            (self.a[0][keep], self.a[1][keep]),
            (self.b[0][keep], self.b[1][keep]),
            self.t[keep],
            self.step[keep],
            None if self.ring is None else self.ring[keep],
        )


@dataclass(frozen=True, eq=False)
class LocatedRings:
    """The ring points a ring decode has located before the fine angle: their crossings, coarse polar
    angle, what was rejected, and the coarse bands every pixel lies in (RingsCodec._bands)."""

    crossings: Crossings
    theta: np.ndarray
    counts: dict[str, int]
    bands: dict[str, np.ndarray]

    @property
    def ends(self) -> tuple[np.ndarray, np.ndarray]:
        """The crossings' two pixels, a then b, as one index of 2M pixels."""
        a, b = self.crossings.a, self.crossings.b
        return np.concatenate([a[0], b[0]]), np.concatenate([a[1], b[1]])
