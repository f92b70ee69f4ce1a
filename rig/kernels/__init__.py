"""The compiled loops (numba), on their own floor: they import numpy and numba only, and every
layer that needs one loads it lazily (rig.lazy), so that a command that does not run one does not
compile it. `dense`: Gray decoding, contrast, plane and ray-to-ray triangulation, kept points and
normals, triangulation angles; `phase`: phase shifting's wrap and unwrap, cued_phase's texture and
status counts; `radial`: the radial codec's levels and coordinates; `rings`: ring samples read by
radius and fine angle, and judged across and along rings; `fill`: the ring surface's
neighbourhoods and height-field fits; `cells`: image points in a grid of cells, for those
neighbour searches; `regions`: evaluation's surface regions. Each is compiled on first use and
cached beside it (__pycache__)."""

import numpy as np

KERNEL = {"nogil": True, "cache": True}  # every loop: released GIL (rig.workers runs bands of rows), cached
Image = np.ndarray  # (H, W), or (3, H, W) for points, directions and normals
