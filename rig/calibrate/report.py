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
MAX_ASPECT_OFF = 0.05  # fy / fx beyond 1 +- this: pixels are square but for a few per cent


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
        aspect = d.K[1, 1] / d.K[0, 0]
        if abs(aspect - 1.0) > MAX_ASPECT_OFF:
            out.append(
                f"{d.name}: fy is {aspect:.3g}x fx ({d.K[1, 1]:.1f} against {d.K[0, 0]:.1f} px); cameras' and "
                "projectors' pixels are square but for a few per cent, so for a projector the pattern description's "
                "periods or code steps for columns and rows may not be what was projected"
            )
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
                "corner_residual_px": _residual_summary(d),
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


def _used_residuals(device: DeviceCalibration) -> list[tuple[int, np.ndarray]]:
    return [(v, r) for v, r in sorted(device.residuals.items()) if v not in device.rejected and len(r)]


def _residual_summary(device: DeviceCalibration) -> dict[str, float] | None:
    """Each corner's reprojection error (px) over the views used: rms, median, 95th percentile, largest."""
    used = _used_residuals(device)
    if not used:
        return None
    lengths = np.linalg.norm(np.concatenate([r for _, r in used]), axis=1)
    p50, p95 = np.percentile(lengths, [50, 95])
    rms = float(np.sqrt(np.mean(lengths**2)))
    return {k: round(float(v), 4) for k, v in {"rms": rms, "p50": p50, "p95": p95, "max": lengths.max()}.items()}


def residuals_png(device: DeviceCalibration, max_width: int = 640) -> bytes:
    """Every corner's reprojection error as an arrow from where it was found, magnified so that the
    95th percentile is 20 image pixels long (one colour per view): a pattern in the arrows (all
    outward at the edges, all one way in one view) is a lens model or a view that does not fit."""
    w, h = device.resolution
    scale = min(1.0, max_width / w)
    image = np.full((round(h * scale), round(w * scale), 3), 28, dtype=np.uint8)
    used = _used_residuals(device)
    summary = _residual_summary(device)
    gain = 20.0 / max(summary["p95"], 1e-6) if summary else 1.0
    for i, (view, residual) in enumerate(used):
        hue = int(180 * ((i * 0.618) % 1.0))
        colour = cv2.cvtColor(np.uint8([[[hue, 200, 255]]]), cv2.COLOR_HSV2BGR)[0, 0].tolist()
        for (x, y), (dx, dy) in zip(device.points[view] * scale, residual, strict=True):
            start = (round(x), round(y))
            cv2.arrowedLine(image, start, (round(x + dx * gain), round(y + dy * gain)), colour, 1, cv2.LINE_AA, 0, 0.3)
    text = f"{device.name}: corner errors x{gain:.0f}" + (f", p95 {summary['p95']:.3f} px" if summary else "")
    cv2.putText(image, text, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (230, 230, 230), 1, cv2.LINE_AA)
    _ok, buf = cv2.imencode(".png", image)
    return buf.tobytes()


def view_jpeg(image: np.ndarray, detection_points: np.ndarray | None, caption: str) -> bytes:
    """One board view as the camera saw it (at most 480 px wide) with the corners found drawn on
    it, and a caption (its number, its error, or why it was not used)."""
    peak = max(int(image.max()), 1)  # a deeper sensor's image, stretched to 8 bits to look at
    shown = image if image.dtype == np.uint8 else (image.astype(np.float32) * (255.0 / peak)).astype(np.uint8)
    shown = cv2.cvtColor(shown, cv2.COLOR_GRAY2BGR) if shown.ndim == 2 else shown.copy()
    scale = min(1.0, 480 / shown.shape[1])
    shown = cv2.resize(
        shown, (round(shown.shape[1] * scale), round(shown.shape[0] * scale)), interpolation=cv2.INTER_AREA
    )
    for x, y in (detection_points if detection_points is not None else np.empty((0, 2))) * scale:
        cv2.circle(shown, (round(x), round(y)), 3, (60, 220, 60), 1, cv2.LINE_AA)
    cv2.rectangle(shown, (0, 0), (shown.shape[1], 22), (28, 28, 28), -1)
    cv2.putText(shown, caption, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (230, 230, 230), 1, cv2.LINE_AA)
    _ok, buf = cv2.imencode(".jpg", shown, [cv2.IMWRITE_JPEG_QUALITY, 80])
    return buf.tobytes()


def view_caption(device: DeviceCalibration, view: int) -> str:
    if view in device.rejected:
        return f"view {view}: not used, {device.rejected[view]}"
    error = device.per_view_rms_px.get(view)
    return f"view {view}: " + (
        f"rms {error:.3f} px, {len(device.points.get(view, []))} corners" if error else "no board found"
    )
