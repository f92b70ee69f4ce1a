"""The allocator's threshold (rig.workers): a rig of large cameras keeps their images in the heap,
so that a sequence's images are not faulted in again each time; a small rig maps them from 6 MB."""

from __future__ import annotations

import resource
import subprocess
import sys
import textwrap

import pytest

from rig.workers import _glibc

pytestmark = pytest.mark.skipif(_glibc() is None, reason="the threshold is glibc's (mallopt); elsewhere a no-op")

# In a fresh process (the threshold is the process's): the minor page faults of making and filling
# a 20 MB array (a 5 MP camera's float32 image) a second time, after the first was freed.
_REFAULTS = textwrap.dedent(
    """
    import resource, sys
    import numpy as np
    from rig.workers import heap_images
    heap_images(int(sys.argv[1]))
    def faults():
        return resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    image = np.ones((2048, 2448), np.float32)
    del image
    before = faults()
    image = np.ones((2048, 2448), np.float32)
    print(faults() - before)
    """
)


def _refaults(camera_pixels: int) -> int:
    ran = subprocess.run(
        [sys.executable, "-c", _REFAULTS, str(camera_pixels)], capture_output=True, text=True, timeout=120, check=True
    )
    return int(ran.stdout.strip().splitlines()[-1])


def test_a_large_cameras_images_stay_in_the_heap_and_a_small_ones_are_mapped() -> None:
    kept, mapped = _refaults(2448 * 2048), _refaults(1280 * 1024)
    # mapped anew: 20 MB faulted in again, in 4 kB pages or (transparent huge pages) 2 MB ones
    assert mapped >= 20 * 2**20 // max(resource.getpagesize(), 2 * 2**20)
    assert kept * 10 <= mapped  # the freed image's pages are used again
