"""Projector-camera calibrations other tools wrote: OpenCV FileStorage (XML, YAML, nested maps too)
and JSON, read into slrig's device models and checked on the way in.

Which tool wrote a file is told by its fields (rig.calibrate.formats: SLStudio, procam-calibration,
OpenCV's stereo sample, slrig's own calibration.yaml; else the usual names), compared exactly, case
and all; a calibration split over several files (OpenCV's intrinsics.yml and extrinsics.yml) is
read from all of them together. What a format defines (which way its R, T map) it decides; what
the file cannot say is an option: the direction where the format does not say, which device is the
world frame, the unit of its lengths, the resolutions where the file has none, the devices' names,
and any field's name (`keys`).

A size stored as a `shape` is (rows, columns) as numpy gives it; any other size is (width,
height) as OpenCV's Size. Matrices may be OpenCV matrices, nested lists, or flat lists.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from pydantic import Field

from rig.calibrate.device_files import device_file, paired
from rig.calibrate.files import calibration_world, load_devices, own_calibration_json
from rig.calibrate.foreign_files import read_values
from rig.calibrate.formats import FIELDS, GENERIC, UNITS_MM, CalibrationFormat, detected, slrig_devices
from rig.calibrate.nested_formats import flattened
from rig.config import Strict
from rig.errors import CalibrationError
from rig.geometry import CameraModel

DISTORTION_LENGTHS = (0, 4, 5, 8, 12, 14)  # OpenCV's: k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]]
SKEW_TOLERANCE = 1e-6  # of fx: a skew below it is rounding, not a lens
ROTATION_TOLERANCE = 1e-3  # |R R^T - I| beyond this is not a rotation (stored values carry ~1e-12)


class ForeignCalibrationOptions(Strict):
    """What a foreign calibration file does not say."""

    camera: str = Field("camera0", min_length=1, description="the camera's device name")
    projector: str = Field("projector0", min_length=1, description="the projector's device name")
    extrinsics: Literal["camera_to_projector", "projector_to_camera"] | None = Field(
        None,
        description="what the file's R, T map: camera_to_projector is X_projector = R X_camera + T "
        "(OpenCV stereoCalibrate with the camera first); default: as the file's format defines it, else that",
    )
    world: Literal["camera", "projector"] | None = Field(
        None, description="the device whose frame is the world's; default: camera (slrig's own files have their own)"
    )
    translation_scale: float | None = Field(
        None, gt=0, le=1e6, description="the file's length unit in millimetres; default: its format's (1 where none)"
    )
    camera_resolution: tuple[int, int] | None = Field(None, description="(width, height) where the file has none")
    projector_resolution: tuple[int, int] | None = Field(None, description="(width, height) where the file has none")
    ignore_projector_distortion: bool = Field(
        False, description="leave out the projector's distortion (where the file's own reconstruction did)"
    )
    keys: dict[str, str] = Field(default_factory=dict, description="field -> the file's name for it (see FIELDS)")


@dataclass(frozen=True, eq=False)
class ForeignCalibration:
    camera: CameraModel
    projector: CameraModel | None  # None: a file of one camera, read for `calibration show`
    rms_px: float | None
    found: dict[str, str]  # field -> the file's name it was read from
    format: str = GENERIC.name  # the format its fields told (rig.calibrate.formats)
    extrinsics: str = "camera_to_projector"  # what the file's R, T mapped
    unit: str = ""  # the file's length unit as its format defines it
    world: str = "camera"  # the frame its devices are posed in: camera, projector, or (slrig's own) board


def read_foreign_calibration(
    paths: Path | Sequence[Path], options: ForeignCalibrationOptions | None = None, *, single_device: bool = False
) -> ForeignCalibration:
    """The camera and projector of the file (or files, read together) at `paths` (with
    `single_device`, a file of one camera alone too: its `projector` None); CalibrationError naming
    the file and field at fault."""
    options = options or ForeignCalibrationOptions()
    unknown = sorted(set(options.keys) - set(FIELDS))
    if unknown:
        raise CalibrationError(
            f"calibration import keys: unknown fields {', '.join(unknown)}; known: {', '.join(FIELDS)}"
        )
    paths = [paths] if isinstance(paths, Path) else list(paths)
    where = " + ".join(str(p) for p in paths)
    own_json = own_calibration_json(paths)
    if own_json is not None:
        camera, projector, _, world = own_calibration(own_json, options)
        found = {"camera_matrix": f"{options.camera}.K", "projector_matrix": f"{options.projector}.K"}
        return ForeignCalibration(camera, projector, None, found, "slrig", "world_to_device", "mm", world)
    values, chosen = _told(where, [(path, read_values(path)) for path in paths])
    if chosen is None:
        return _own(where, slrig_devices(values), options, str(values.get("world", "board")))
    fields = _Fields(where, values, options, chosen)
    camera_k = fields.matrix("camera_matrix", required=True)
    scale, unit = _unit(fields, options)
    if fields.raw("projector_matrix", required=False) is None:
        if not single_device:
            looked = ", ".join(fields.names("projector_matrix")) or "nothing"
            raise CalibrationError(
                f"calibration file {where}: holds a camera alone (no projector_matrix: looked for {looked}, as "
                f"{chosen.name}); a reconstruction needs the projector's calibration too: give its file as well"
            )
        camera = _model(fields, "camera", camera_k, (np.eye(3), np.zeros(3)), options.camera_resolution)
        return ForeignCalibration(camera, None, fields.number("rms"), fields.found, chosen.name, "", unit)
    projector_k = fields.matrix("projector_matrix", required=True)
    rotation = _rotation(fields, fields.matrix("rotation", required=True))
    translation = fields.vector("translation", 3) * scale
    direction = options.extrinsics or chosen.extrinsics or "camera_to_projector"
    if direction == "projector_to_camera":  # X_c = R X_p + T  ->  X_p = R^T X_c - R^T T
        rotation, translation = rotation.T, -rotation.T @ translation
    if options.world in (None, "camera"):
        camera_pose, projector_pose = (np.eye(3), np.zeros(3)), (rotation, translation)
    else:
        camera_pose, projector_pose = (rotation.T, -rotation.T @ translation), (np.eye(3), np.zeros(3))
    camera = _model(fields, "camera", camera_k, camera_pose, options.camera_resolution)
    projector = _model(fields, "projector", projector_k, projector_pose, options.projector_resolution)
    if options.ignore_projector_distortion:
        projector = dataclasses.replace(projector, dist=np.zeros(5))
    rms = fields.number("rms")
    world = options.world or "camera"
    return ForeignCalibration(camera, projector, rms, fields.found, chosen.name, direction, unit, world)


def _told(where: str, files: list[tuple[Path, dict[str, Any]]]) -> tuple[dict[str, Any], CalibrationFormat | None]:
    """The files' fields as one calibration's, and the format that names them (None: slrig's own)."""
    devices = [(path, device_file(path, values)) for path, values in files]
    if any(device is not None for _, device in devices):
        rest = _merged([(p, v) for (p, v), (_, d) in zip(files, devices, strict=True) if d is None])
        return paired([d for _, d in devices if d is not None], rest)
    try:
        values = flattened(_merged(files))
    except ValueError as exc:
        raise CalibrationError(f"calibration file {where}: {exc}") from None
    if slrig_devices(values):
        return values, None
    try:
        return values, detected(values)
    except ValueError as exc:
        raise CalibrationError(f"calibration file {where}: {exc}") from None


def _unit(fields: _Fields, options: ForeignCalibrationOptions) -> tuple[float, str]:
    """Millimetres per unit of the file's lengths, and that unit's name as the file or format gives it."""
    chosen = fields.format
    named = fields.values.get(chosen.unit_field) if chosen.unit_field else None
    if options.translation_scale is not None:
        return options.translation_scale, chosen.unit if named is None else str(named)
    if named is None:
        return chosen.scale_mm or 1.0, chosen.unit
    key = str(named).strip().lower()
    if key not in UNITS_MM:
        raise fields.error(
            str(chosen.unit_field),
            f"{named!r} is not a unit slrig knows ({', '.join(UNITS_MM)}); give --translation-scale",
        )
    return UNITS_MM[key], str(named)


def _merged(files: list[tuple[Path, dict[str, Any]]]) -> dict[str, Any]:
    """Every file's fields together; CalibrationError naming both files where two give one field."""
    values: dict[str, Any] = {}
    origin: dict[str, Path] = {}
    for path, found in files:
        for key, value in found.items():
            if key in values:
                raise CalibrationError(f"calibration file {path}: {key}: also in {origin[key]}; give it once")
            values[key], origin[key] = value, path
    return values


def own_calibration(path: Path, options: ForeignCalibrationOptions) -> tuple[CameraModel, CameraModel, str, str]:
    """The options' camera and projector of slrig's calibration.json (its hash checked), the
    hash, and the frame it is written in."""
    refuse_for_own(str(path), options)
    (camera, projector), digest = load_devices(path, (options.camera, options.projector))
    return camera, projector, digest, calibration_world(path)


def refuse_for_own(where: str, options: ForeignCalibrationOptions) -> None:
    """CalibrationError naming the option where one that slrig's own calibration files already
    answer (their world frame, direction, unit and names) is given anyway: not ignored silently."""
    given = [
        name
        for name, default in (("world", None), ("extrinsics", None), ("translation_scale", None), ("keys", {}))
        if getattr(options, name) != default
    ]
    given += [name for name in ("camera_resolution", "projector_resolution") if getattr(options, name) is not None]
    if given:
        flags = ", ".join(f"--{name.replace('_', '-')}" for name in given)
        raise CalibrationError(
            f"calibration file {where}: {flags}: slrig's own calibration says these itself (its devices in its "
            "own world frame, in mm); give them only for another tool's file"
        )


def _own(
    where: str, devices: dict[str, dict[str, Any]], options: ForeignCalibrationOptions, world: str
) -> ForeignCalibration:
    """slrig's own calibration.yaml: the options' devices, posed as the file says (world to device)."""
    refuse_for_own(where, options)
    models = {}
    for name in (options.camera, options.projector):
        if name not in devices:
            raise CalibrationError(f"calibration file {where}: has no device {name} (its: {', '.join(devices)})")
        d = devices[name]
        try:
            models[name] = CameraModel(
                width=int(d["image_width"]),
                height=int(d["image_height"]),
                K=np.asarray(d["camera_matrix"], float).reshape(3, 3),
                R=np.asarray(d["rotation_world_to_device"], float).reshape(3, 3),
                t=np.asarray(d["translation_world_to_device"], float).ravel(),
                dist=np.asarray(d.get("distortion_coefficients", np.zeros(5)), float).ravel()[:5],
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationError(f"calibration file {where}: {name}: cannot read {exc}") from None
    rms = devices[options.projector].get("rms_px")
    found = {
        "camera_matrix": f"{options.camera}.camera_matrix",
        "projector_matrix": f"{options.projector}.camera_matrix",
    }
    return ForeignCalibration(
        models[options.camera], models[options.projector], None if rms is None else float(rms), found, "slrig",
        "world_to_device", "mm", world,
    )  # fmt: skip


def check_resolution(model: CameraModel, size: tuple[int, int], what: str, source: str, path: Path | str) -> None:
    """CalibrationError where the size (width, height) `source` gives does not fit the calibrated device."""
    if (model.width, model.height) != tuple(size):
        raise CalibrationError(
            f"calibration file {path}: the {what} is calibrated for {model.width}x{model.height}, "
            f"{source} {size[0]}x{size[1]}"
        )


class _Fields:
    """The file's values, looked up by field under the option's name or the format's, exactly."""

    def __init__(
        self, where: str, values: dict[str, Any], options: ForeignCalibrationOptions, chosen: CalibrationFormat
    ) -> None:
        self.where, self.values, self.options, self.format = where, values, options, chosen
        self.found: dict[str, str] = {}

    def error(self, name: str, reason: str) -> CalibrationError:
        return CalibrationError(f"calibration file {self.where}: {name}: {reason}")

    def names(self, field: str) -> tuple[str, ...]:
        if field in self.options.keys:
            return (self.options.keys[field],)
        return self.format.names.get(field, ())

    def raw(self, field: str, required: bool) -> Any:
        names = self.names(field)
        present = [n for n in names if n in self.values]
        if len(present) > 1:
            raise self.error(field, f"given twice, as {' and '.join(present)}; name one in the options' keys")
        if not present:
            if required:
                raise self.error(field, f"missing (looked for {', '.join(names) or 'nothing'}, as {self.format.name})")
            return None
        self.found[field] = present[0]
        return self.values[present[0]]

    def array(self, field: str, required: bool = False) -> np.ndarray | None:
        value = self.raw(field, required)
        if value is None:
            return None
        try:
            found = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise self.error(self.found[field], "not a matrix of numbers") from None
        if not np.all(np.isfinite(found)):
            raise self.error(self.found[field], "holds a value that is not a finite number")
        return found

    def matrix(self, field: str, required: bool = False) -> np.ndarray:
        found = self.array(field, required)
        assert found is not None
        if field != "rotation" and found.size != 9:
            raise self.error(self.found[field], f"{found.size} values where a 3x3 matrix has 9")
        return found.reshape(3, 3) if found.size == 9 else found

    def vector(self, field: str, size: int) -> np.ndarray:
        found = self.array(field, required=True)
        assert found is not None
        if found.size != size:
            raise self.error(self.found[field], f"{found.size} values where {size} belong")
        return found.ravel()

    def number(self, field: str) -> float | None:
        found = self.array(field)
        return None if found is None or found.size != 1 else float(found.ravel()[0])


def _rotation(fields: _Fields, value: np.ndarray) -> np.ndarray:
    name = fields.found["rotation"]
    if value.size == 3:  # a rotation vector (Rodrigues), as OpenCV's solvers return
        return cv2.Rodrigues(value.reshape(3, 1))[0]
    if value.size != 9:
        raise fields.error(name, f"{value.size} values: neither a 3x3 rotation nor a rotation vector")
    rotation = value.reshape(3, 3)
    off = float(np.abs(rotation @ rotation.T - np.eye(3)).max())
    determinant = float(np.linalg.det(rotation))
    if off > ROTATION_TOLERANCE or determinant < 0:
        raise fields.error(
            name, f"not a rotation (R R^T differs from the identity by up to {off:.3g}, determinant {determinant:.3g})"
        )
    return rotation


def _model(
    fields: _Fields,
    device: str,
    k: np.ndarray,
    pose: tuple[np.ndarray, np.ndarray],
    resolution: tuple[int, int] | None,
) -> CameraModel:
    name = fields.found[f"{device}_matrix"]
    if k[0, 0] <= 0 or k[1, 1] <= 0 or not np.allclose(k[2], [0.0, 0.0, 1.0]):
        raise fields.error(name, "not a camera matrix (fx, fy > 0 and a last row 0 0 1)")
    if abs(k[0, 1]) > SKEW_TOLERANCE * k[0, 0] or k[1, 0] != 0:
        raise fields.error(name, f"a skew of {k[0, 1]:.6g} (K[0,1]); slrig's camera model has none")
    dist = fields.array(f"{device}_distortion")
    dist = np.zeros(5) if dist is None else dist.ravel()
    if dist.size not in DISTORTION_LENGTHS:
        raise fields.error(
            fields.found[f"{device}_distortion"], f"{dist.size} coefficients; OpenCV's are 4, 5, 8, 12 or 14"
        )
    if np.any(dist[5:] != 0):
        raise fields.error(
            fields.found[f"{device}_distortion"],
            "terms beyond k1 k2 p1 p2 k3 are not zero; slrig's camera model has those five only",
        )
    width, height = _size(fields, f"{device}_size", resolution)
    return CameraModel(width=width, height=height, K=k, R=pose[0], t=pose[1], dist=dist[:5])


def _size(fields: _Fields, field: str, given: tuple[int, int] | None) -> tuple[int, int]:
    device = field.split("_")[0]
    found = fields.array(field)
    if found is None:
        width, height = fields.number(f"{device}_width"), fields.number(f"{device}_height")
        if width is not None and height is not None:
            found = np.array([width, height])
    if found is None:
        if given is None:
            looked = ", ".join(fields.names(field) + fields.names(f"{device}_width")) or "nothing"
            raise fields.error(
                field, f"missing (looked for {looked}); give {device}_resolution (--{device}-resolution)"
            )
        return given
    name = fields.found.get(field) or f"{fields.found[f'{device}_width']}, {fields.found[f'{device}_height']}"
    values = found.ravel()
    if values.size != 2 or np.any(values <= 0) or np.any(values != np.round(values)):
        raise fields.error(name, "not a size of two positive whole numbers")
    rows_first = "shape" in name.lower() or name in fields.format.rows_first
    width, height = (values[1], values[0]) if rows_first else (values[0], values[1])
    size = (int(width), int(height))
    if given is not None and tuple(given) != size:
        raise fields.error(name, f"{size[0]}x{size[1]} in the file, {given[0]}x{given[1]} in the options")
    return size


def write_opencv_stereo(path: Path, camera: CameraModel, projector: CameraModel) -> Path:
    """A camera-projector pair as OpenCV's stereoCalibrate gives it, camera first (X_projector =
    R X_camera + T), with procam-calibration's field names and sizes as shapes: what other tools read
    back, and what this module reads with its default options."""
    rotation = projector.R @ camera.R.T
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, model in (("img_shape", camera), ("proj_shape", projector)):
        storage.write(key, np.array([[model.height], [model.width]], float))
    for key, model in (("cam", camera), ("proj", projector)):
        dist = np.zeros(5)
        dist[: len(model.dist)] = np.ravel(model.dist)[:5]
        storage.write(f"{key}_int", np.asarray(model.K, float))
        storage.write(f"{key}_dist", dist.reshape(1, 5))
    storage.write("R", rotation)
    storage.write("T", (projector.t - rotation @ camera.t).reshape(3, 1))
    storage.release()
    return path
