"""Device drivers for slrig: projectors, cameras, transports and the simulated bench.

This package knows nothing of scans: `rig` imports `drivers`, never the other way round.
"""

import os as _os

# OpenCV's V4L2 backend waits for a frame in select() for OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT seconds
# (default 10), read once when cv2 loads; slrig's capture timeouts are shorter, so bound it first.
_os.environ.setdefault("OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT", "2")
# OpenCV decodes an image of up to OPENCV_IO_MAX_IMAGE_PIXELS (default 2**30, 2 GB at 16 bits),
# read once when cv2 loads. slrig judges images by their headers first (rig.store.image_header);
# this is the backstop for a header it misjudged: 2**28 pixels, far above any camera's frame.
_os.environ.setdefault("OPENCV_IO_MAX_IMAGE_PIXELS", str(1 << 28))
