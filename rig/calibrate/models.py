"""Lens models for few views: the constraints other calibration tools offer, and the choice among
them by what the views support.

A model is a distortion (k1; k1 and k2; those and the tangential p1, p2; all five with k3) and two
optional constraints: the principal point fixed mid-image, and square pixels (fx = fy). With four
or five views, a model with every term free fits the views' noise and predicts the next view badly.

`auto` starts from the richest distortion and pares it from the top (k3, then the tangential pair,
then k2) while the term's fitted value lies within SIGNIFICANCE standard deviations (OpenCV's, from
the fit) of zero, stopping at the first term the views determine. It leaves the centre and the
aspect free: on the simulated bench, whose camera has its centre exactly mid-image and square
pixels, fixing them made the scan worse (0.102 and 0.089 mm rms against 0.086, 10 views), since a
fraction of a pixel of convention anywhere in the chain then lands in the extrinsics; and a
projector's centre is far from mid-image by its lens shift. Ask for them (+fixed_centre,
+fixed_aspect) where the views are too few to place the centre.
The views left out then check the choice: each view in turn (or an eighth of them) is left out, the
lens fitted to the others, the view's board placed by solvePnP and its reprojection error taken;
should the chosen model predict views left out worse than the model with every term but k3 by more
than HELD_OUT_TOLERANCE, that model is taken instead. The report keeps both held-out errors and the
standard deviation of every free parameter, so an under-determined calibration shows itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from rig.errors import CalibrationError

DISTORTIONS: dict[str, int] = {  # simplest first; OpenCV calibrateCamera flags
    "k1": cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST,
    "k1k2": cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST,
    "k1k2_tangential": cv2.CALIB_FIX_K3,
    "full": 0,
}
REFERENCE = "k1k2_tangential"  # slrig's model before the choice; also finds outlier views
SIGNIFICANCE = 3.0
HELD_OUT_TOLERANCE = 1.05
MAX_FOLDS = 8
PARAMETERS = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")


@dataclass(frozen=True)
class LensModel:
    distortion: str = REFERENCE
    fix_centre: bool = False
    fix_aspect: bool = False

    @classmethod
    def parse(cls, name: str) -> LensModel | None:
        """The model a name (as `name` writes it) stands for; None for auto."""
        if name == "auto":
            return None
        distortion, *fixed = name.split("+")
        return cls(distortion, "fixed_centre" in fixed, "fixed_aspect" in fixed)

    @property
    def name(self) -> str:
        fixed = [n for n, f in (("fixed_centre", self.fix_centre), ("fixed_aspect", self.fix_aspect)) if f]
        return "+".join([self.distortion, *fixed])

    @property
    def flags(self) -> int:
        flags = DISTORTIONS[self.distortion]
        if self.fix_centre:
            flags |= cv2.CALIB_FIX_PRINCIPAL_POINT
        if self.fix_aspect:
            flags |= cv2.CALIB_FIX_ASPECT_RATIO
        return flags


@dataclass
class LensFit:
    """One model fitted to a device's views."""

    model: LensModel
    rms_px: float
    K: np.ndarray
    dist: np.ndarray  # k1, k2, p1, p2, k3
    poses: dict[int, tuple[np.ndarray, np.ndarray]]  # view -> (rotation board -> device, translation)
    per_view_rms_px: dict[int, float]
    std: dict[str, float]  # free parameter -> its standard deviation
    held_out_px: dict[str, float] = field(default_factory=dict)  # model name -> held-out rms, where checked


Views = dict[int, np.ndarray]


def fit(model: LensModel, objects: Views, images: Views, size: tuple[int, int]) -> LensFit:
    """Fit `model` to the views' board points (N, 3) and image points (N, 2)."""
    views = sorted(objects)
    flags, start = model.flags, np.eye(3)
    if model.fix_aspect or model.fix_centre:
        start = _start(model, objects, images, size)
        flags |= cv2.CALIB_USE_INTRINSIC_GUESS
    rms, K, dist, rvecs, tvecs, std, _, per_view = cv2.calibrateCameraExtended(
        [objects[v].astype(np.float32) for v in views],
        [images[v].astype(np.float32).reshape(-1, 1, 2) for v in views],
        size,
        start,
        None,
        flags=flags,
    )
    return LensFit(
        model,
        float(rms),
        K,
        np.ravel(dist)[:5],
        {v: (cv2.Rodrigues(r)[0], np.ravel(t)) for v, r, t in zip(views, rvecs, tvecs, strict=True)},
        {v: float(e) for v, e in zip(views, np.ravel(per_view), strict=True)},
        {name: float(s) for name, s in zip(PARAMETERS, np.ravel(std), strict=False) if s > 0},
    )


def _start(model: LensModel, objects: Views, images: Views, size: tuple[int, int]) -> np.ndarray:
    """A start for a constrained fit: the free model's focal length and centre (OpenCV's own start
    puts the centre mid-image, from where a projector's, near or past an edge by its lens shift, is
    not found with the aspect fixed), the centre clamped into the image as OpenCV requires."""
    free = fit(LensModel(model.distortion), objects, images, size).K
    focal = (free[0, 0] + free[1, 1]) / 2
    if model.fix_centre:
        cx, cy = (size[0] - 1) / 2, (size[1] - 1) / 2
    else:
        cx, cy = min(max(free[0, 2], 0.0), size[0] - 1.0), min(max(free[1, 2], 0.0), size[1] - 1.0)
    fx, fy = (focal, focal) if model.fix_aspect else (free[0, 0], free[1, 1])
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def held_out_error(model: LensModel, objects: Views, images: Views, size: tuple[int, int]) -> float:
    """Rms reprojection error (px) of views left out of the fit, each placed by solvePnP."""
    views = sorted(objects)
    folds = min(len(views), MAX_FOLDS)
    squared, count = 0.0, 0
    for fold in range(folds):
        left_out = [v for k, v in enumerate(views) if k % folds == fold]
        kept = [v for v in views if v not in left_out]
        try:
            lens = fit(model, {v: objects[v] for v in kept}, {v: images[v] for v in kept}, size)
        except cv2.error:
            return float("inf")
        for v in left_out:
            found, rvec, tvec = cv2.solvePnP(objects[v], images[v], lens.K, lens.dist)
            if not found:
                return float("inf")
            projected, _ = cv2.projectPoints(objects[v], rvec, tvec, lens.K, lens.dist)
            squared += float(np.sum((projected.reshape(-1, 2) - images[v]) ** 2))
            count += len(images[v])
    return float(np.sqrt(squared / count))


def _significant(lens: LensFit, term: str, size: tuple[int, int]) -> bool:
    """Whether the views determine `term` away from the value its constraint would fix."""
    std, K, dist = lens.std, lens.K, lens.dist

    def beyond(value: float, sigma: float) -> bool:
        return abs(value) > SIGNIFICANCE * sigma

    if term == "k3":
        return beyond(dist[4], std.get("k3", np.inf))
    if term == "tangential":
        return beyond(dist[2], std.get("p1", np.inf)) or beyond(dist[3], std.get("p2", np.inf))
    if term == "k2":
        return beyond(dist[1], std.get("k2", np.inf))
    if term == "aspect":
        return beyond(K[0, 0] - K[1, 1], float(np.hypot(std.get("fx", np.inf), std.get("fy", np.inf))))
    return beyond(K[0, 2] - (size[0] - 1) / 2, std.get("cx", np.inf)) or beyond(
        K[1, 2] - (size[1] - 1) / 2, std.get("cy", np.inf)
    )


def _simpler(model: LensModel, term: str) -> LensModel:
    if term in ("k3", "tangential", "k2"):
        order = list(DISTORTIONS)
        return LensModel(order[order.index(model.distortion) - 1], model.fix_centre, model.fix_aspect)
    if term == "aspect":
        return LensModel(model.distortion, model.fix_centre, True)
    return LensModel(model.distortion, True, model.fix_aspect)


def choose(requested: LensModel | None, objects: Views, images: Views, size: tuple[int, int]) -> LensFit:
    """The requested model fitted, or (None: auto) the simplest one the views support."""
    if requested is not None:
        return fit(requested, objects, images, size)
    lens = fit(LensModel("full"), objects, images, size)
    for term in ("k3", "tangential", "k2"):
        if _significant(lens, term, size):
            break
        lens = fit(_simpler(lens.model, term), objects, images, size)
    if len(objects) < 4:  # none can be left out
        return lens
    reference = LensModel(REFERENCE)
    errors = {m.name: held_out_error(m, objects, images, size) for m in {lens.model, reference}}
    if not np.isfinite(min(errors.values())):
        raise CalibrationError("no lens model could be fitted to the views with one left out")
    if errors[lens.model.name] > HELD_OUT_TOLERANCE * errors[reference.name]:
        lens = fit(reference, objects, images, size)
    lens.held_out_px = {name: round(e, 4) for name, e in errors.items()}
    return lens
