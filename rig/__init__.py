"""slrig: everything that is not a device: patterns, geometry, scans, storage, service, CLI."""

__version__ = "0.1.0"

import drivers as _drivers  # noqa: F401 - sets OpenCV's V4L2 read timeout before cv2 is imported
