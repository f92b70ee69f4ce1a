"""The V4L2 controls slrig sets through OpenCV's V4L2 backend, as data: the OpenCV property, the
V4L2 control or ioctl it becomes, its unit, and the values the document allows. The VideoCapture
fake (drivers.fakes.v4l2) refuses (set() returns False, nothing changes) what this table refuses,
and tests/test_protocol_tables.py checks every set the driver makes against it.

Sources: the Linux media UAPI, "Camera Control Reference" (V4L2_CID_EXPOSURE_AUTO's menu,
V4L2_CID_EXPOSURE_ABSOLUTE in 100 us units), "VIDIOC_G_FMT" and "VIDIOC_REQBUFS"; OpenCV
modules/videoio/src/cap_v4l.cpp for which property becomes which control (without range
normalisation, the default); ../shared/reference/hardware.md section 7.1.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2

UAPI = "Linux media UAPI, Camera Control Reference"
FMT = "Linux media UAPI, VIDIOC_G_FMT / VIDIOC_S_FMT (struct v4l2_pix_format)"


@dataclass(frozen=True)
class V4l2Control:
    prop: int  # cv2.CAP_PROP_*
    control: str  # the V4L2 control or ioctl field it sets
    unit: str
    accepts: Callable[[float], bool]
    source: str


def _whole(low: int, high: int) -> Callable[[float], bool]:
    return lambda value: float(value).is_integer() and low <= value <= high


CONTROLS = {
    c.prop: c
    for c in (
        V4l2Control(
            cv2.CAP_PROP_AUTO_EXPOSURE,
            "V4L2_CID_EXPOSURE_AUTO",
            "menu: 0 auto, 1 manual, 2 shutter priority, 3 aperture priority",
            lambda value: value in (0, 1, 2, 3),
            UAPI,
        ),
        V4l2Control(cv2.CAP_PROP_EXPOSURE, "V4L2_CID_EXPOSURE_ABSOLUTE", "100 us", _whole(1, 2**31 - 1), UAPI),
        V4l2Control(cv2.CAP_PROP_GAIN, "V4L2_CID_GAIN", "device units", _whole(0, 2**31 - 1), UAPI),
        V4l2Control(cv2.CAP_PROP_FRAME_WIDTH, "v4l2_pix_format.width", "pixels", _whole(1, 65535), FMT),
        V4l2Control(cv2.CAP_PROP_FRAME_HEIGHT, "v4l2_pix_format.height", "pixels", _whole(1, 65535), FMT),
        V4l2Control(cv2.CAP_PROP_FOURCC, "v4l2_pix_format.pixelformat", "four characters", _whole(1, 2**32 - 1), FMT),
        V4l2Control(
            cv2.CAP_PROP_BUFFERSIZE,
            "v4l2_requestbuffers.count",
            "buffers",
            _whole(1, 10),  # OpenCV's MAX_V4L_BUFFERS
            "Linux media UAPI, VIDIOC_REQBUFS; OpenCV cap_v4l.cpp MAX_V4L_BUFFERS",
        ),
    )
}


def refuses(prop: int, value: float) -> str | None:
    """Why the table refuses setting `prop` to `value`, or None."""
    control = CONTROLS.get(prop)
    if control is None:
        return f"property {prop} is not a control slrig sets"
    if not control.accepts(value):
        return f"{control.control}: {value!r} is not a valid value ({control.unit})"
    return None
