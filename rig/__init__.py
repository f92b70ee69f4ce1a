"""slrig: everything that is not a device: patterns, geometry, scans, storage, service, CLI."""

__version__ = "0.1.0"

from rig.workers import tune_malloc as _tune_malloc

_tune_malloc()  # first: before numpy and OpenCV start their threads and allocate

import drivers as _drivers  # noqa: E402, F401 - sets OpenCV's V4L2 read timeout before cv2 is imported
