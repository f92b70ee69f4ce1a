"""A diamond-pixel DMD (the LightCrafter 4500's DLP4500: 912 x 1140 mirrors). Its mirrors sit in
rows half a mirror pitch apart, each row shifted by half a mirror against the one before, so that
the mirror columns of even and odd rows interleave into twice as many virtual columns, square in
the plane: mirror (c, r) lies over virtual columns 2c + (r mod 2) and the next, its centre half a
virtual column right of the first. A pattern of virtual columns (1824 x 1140) is shown by sampling
it at each mirror's first virtual column; the virtual image a mirror image makes is what the
simulated bench projects for a diamond DMD."""

from __future__ import annotations

import numpy as np

MIRROR_CENTRE = 0.5  # a mirror's centre, in virtual columns right of the first it covers


def first_virtual_column(width: int, height: int) -> np.ndarray:
    """(height, width) virtual column index of each mirror's first virtual column."""
    return 2 * np.arange(width)[None, :] + (np.arange(height)[:, None] & 1)


def mirror_image(virtual: np.ndarray) -> np.ndarray:
    """The mirrors' image (H, W/2) showing a virtual-column image (H, W)."""
    height, width = virtual.shape[:2]
    columns = first_virtual_column(width // 2, height)
    return virtual[np.arange(height)[:, None], columns]


def virtual_image(mirrors: np.ndarray) -> np.ndarray:
    """What the mirrors (H, W) show on the virtual grid (H, 2W): each mirror over its two virtual
    columns, odd rows a column to the right (their first virtual column lies between mirrors: dark)."""
    doubled = np.repeat(mirrors, 2, axis=1)
    out = doubled.copy()
    out[1::2, 1:] = doubled[1::2, :-1]
    out[1::2, 0] = 0
    return out
