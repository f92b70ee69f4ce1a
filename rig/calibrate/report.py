"""The quality report a person can act on: errors per device and view, rejected views and why,
where the corners fell in each image, and warnings with their reasons."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from rig.calibrate.solve import DeviceCalibration

GRID = 8  # coverage is the fraction of an 8x8 grid of image cells that hold a corner
RECOMMENDED_VIEWS = 8
MIN_COVERAGE = 0.4
MAX_RMS_PX = {"camera": 0.5, "projector": 1.0}
MAX_FOCAL_STD = 0.01  # of the focal length: more, and the views do not determine the lens
MAX_CENTRE_STD = 0.02  # of the image's width or height


def coverage(device: DeviceCalibration) -> float:
    w, h = device.resolution
    cells = np.zeros((GRID, GRID), dtype=bool)
    for view, points in device.points.items():
        if view in device.rejected or len(points) == 0:
            continue
        col = np.clip((points[:, 0] / w * GRID).astype(int), 0, GRID - 1)
        row = np.clip((points[:, 1] / h * GRID).astype(int), 0, GRID - 1)
        cells[row, col] = True
    return float(cells.mean())


def warnings(devices: list[DeviceCalibration]) -> list[str]:
    out = []
    for d in devices:
        used = len(d.per_view_rms_px) - sum(v in d.per_view_rms_px for v in d.rejected)
        if used < RECOMMENDED_VIEWS:
            out.append(f"{d.name}: only {used} views used; {RECOMMENDED_VIEWS}-20 give a trustworthy result")
        share = coverage(d)
        if share < MIN_COVERAGE:
            out.append(
                f"{d.name}: corners cover {share:.0%} of the image (under {MIN_COVERAGE:.0%}); add views "
                "with the board near the image's edges and corners, where lens distortion is strongest"
            )
        limit = MAX_RMS_PX[d.kind]
        if d.rms_px > limit:
            out.append(
                f"{d.name}: reprojection error {d.rms_px:.2f} px is above {limit} px; check focus, board "
                "flatness, exposure and, for a projector, its response (gamma) and frame sync"
            )
        out += _undetermined(d)
        if d.stereo_rms_px is not None and d.stereo_rms_px > 2 * limit:
            out.append(f"{d.name}: stereo error {d.stereo_rms_px:.2f} px; the views may be inconsistent")
    return out


def _undetermined(d: DeviceCalibration) -> list[str]:
    """Parameters the views leave uncertain (OpenCV's standard deviations against their scale)."""
    scale = {"fx": d.K[0, 0] * MAX_FOCAL_STD, "fy": d.K[1, 1] * MAX_FOCAL_STD}
    scale |= {"cx": d.resolution[0] * MAX_CENTRE_STD, "cy": d.resolution[1] * MAX_CENTRE_STD}
    loose = [f"{name} +-{d.std[name]:.1f} px" for name in scale if d.std.get(name, 0.0) > scale[name]]
    if not loose:
        return []
    return [
        f"{d.name}: the views leave {', '.join(loose)} uncertain (model {d.model}); add views at other "
        "tilts and distances, or choose a simpler model (calibration.model)"
    ]


def report(devices: list[DeviceCalibration]) -> dict[str, Any]:
    return {
        "devices": {
            d.name: {
                "kind": d.kind,
                "rms_px": round(d.rms_px, 4),
                "stereo_rms_px": None if d.stereo_rms_px is None else round(d.stereo_rms_px, 4),
                "views_used": sorted(v for v in d.per_view_rms_px if v not in d.rejected),
                "per_view_rms_px": {str(v): round(e, 4) for v, e in sorted(d.per_view_rms_px.items())},
                "rejected_views": {str(v): reason for v, reason in sorted(d.rejected.items())},
                "coverage": round(coverage(d), 3),
                "model": d.model,
                "std": {name: round(value, 6) for name, value in d.std.items()},
                "held_out_rms_px": d.held_out_px,
            }
            for d in devices
        },
        "warnings": warnings(devices),
    }


def coverage_png(device: DeviceCalibration, max_width: int = 640) -> bytes:
    """The device's image area with every corner used (one colour per view) and the 8x8 grid,
    covered cells lit: where the board has been, and where it has not."""
    w, h = device.resolution
    scale = min(1.0, max_width / w)
    width, height = round(w * scale), round(h * scale)
    image = np.full((height, width, 3), 28, dtype=np.uint8)
    for k in range(1, GRID):
        cv2.line(image, (round(k * width / GRID), 0), (round(k * width / GRID), height), (70, 70, 70), 1)
        cv2.line(image, (0, round(k * height / GRID)), (width, round(k * height / GRID)), (70, 70, 70), 1)
    for i, (view, points) in enumerate(sorted(device.points.items())):
        hue = int(180 * ((i * 0.618) % 1.0))
        colour = cv2.cvtColor(np.uint8([[[hue, 200, 255]]]), cv2.COLOR_HSV2BGR)[0, 0].tolist()
        rejected = view in device.rejected
        for x, y in points * scale:
            cv2.circle(image, (round(x), round(y)), 2, (90, 90, 90) if rejected else colour, -1)
    cv2.putText(
        image,
        f"{device.name}: {coverage(device):.0%} covered, rms {device.rms_px:.3f} px",
        (8, 20),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.5,
        (230, 230, 230),
        1,
        cv2.LINE_AA,
    )
    _ok, buf = cv2.imencode(".png", image)
    return buf.tobytes()
