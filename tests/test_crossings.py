"""The ring codec's edge crossings (rig.patterns.crossings): the compiled count-and-list pass
against numpy's rule."""

from __future__ import annotations

import numpy as np
import pytest

from rig.patterns.crossings import Crossings


def _numpy_candidates(edge: np.ndarray, min_contrast: float) -> tuple[np.ndarray, ...]:
    """Crossings.candidates' rule in numpy passes (as it was written before its compiled loop)."""
    gy, gx = np.gradient(edge)
    steep = np.abs(gy) >= np.abs(gx)
    parts = []
    for axis in (0, 1):
        a = (slice(None, -1), slice(None)) if axis == 0 else (slice(None), slice(None, -1))
        b = (slice(1, None), slice(None)) if axis == 0 else (slice(None), slice(1, None))
        d1, d2 = edge[a], edge[b]
        step = d1 - d2
        found = ((d1 >= 0) != (d2 >= 0)) & (np.abs(step) >= min_contrast)
        found &= steep[a] if axis == 0 else ~steep[a]
        rows, cols = np.nonzero(found)
        parts.append(
            (rows, cols, rows + (axis == 0), cols + (axis == 1), d1[rows, cols] / step[rows, cols], step[rows, cols])
        )
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(6))


@pytest.mark.parametrize("shape", [(2, 2), (3, 7), (61, 45)])
def test_ring_crossings_compiled_are_numpys_bit_for_bit(shape: tuple[int, int]) -> None:
    """The edge's crossings from the compiled count-and-list passes: numpy's, in its order and to
    the bit, also where pixels lie exactly on a ring (0) and slopes tie."""
    rng = np.random.default_rng(shape[0])
    edge = (rng.integers(-3, 4, shape) / 8).astype(np.float32)  # 8-bit-like: many zeros and ties
    edge[::3] = rng.normal(0, 0.3, (len(edge[::3]), shape[1])).astype(np.float32)
    edge[0, :2] = 0.5, -0.5  # at least one crossing, between columns
    edge[-1, -1] = np.nan  # a pixel no frame read: no crossing with it
    found = Crossings.candidates(edge, 0.1)
    expected = _numpy_candidates(edge, 0.1)
    assert len(found.t) == len(expected[0]) > 0
    for got, want in zip((*found.a, *found.b, found.t, found.step), expected, strict=True):
        assert np.array_equal(got, want) and got.dtype == (np.float64 if got is found.t else want.dtype)
