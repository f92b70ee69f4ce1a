"""slrig: everything that is not a device: patterns, geometry, scans, storage, service, CLI."""

__version__ = "0.1.0"

import drivers as _drivers  # noqa: F401 - sets OpenCV's V4L2 read timeout before cv2 is imported
from rig.pipeline.workers import share_malloc_arena as _share_malloc_arena

_share_malloc_arena()
