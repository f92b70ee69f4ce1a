"""Device drivers for slrig: projectors, cameras, transports and the simulated bench.

This package knows nothing of scans: `rig` imports `drivers`, never the other way round.
"""

import os as _os

# OpenCV's V4L2 backend waits for a frame in select() for OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT seconds
# (default 10), read once when cv2 loads; slrig's capture timeouts are shorter, so bound it first.
_os.environ.setdefault("OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT", "2")
