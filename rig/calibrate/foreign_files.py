"""The fields of a calibration file as another tool wrote it, whatever its container: OpenCV
FileStorage (XML, YAML, JSON; nested maps too), plain YAML (Kalibr's, ROS's), JSON, a MATLAB .mat
(v7 or older, as `save` writes a struct) and a folder of 3DUNDERWORLD's text matrices. Which tool
wrote the fields is rig.calibrate.formats' question, not this module's."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from rig.errors import CalibrationError

# 3DUNDERWORLD-SLS writes a camera's calibration as four text files, one matrix row per line
UNDERWORLD_TEXTS = {
    "cam_matrix": "cam_matrix.txt",
    "cam_distortion": "cam_distortion.txt",
    "cam_rotation_matrix": "cam_rotation_matrix.txt",
    "cam_trans_vectror": "cam_trans_vectror.txt",  # [sic], as the tool names it
}


def read_values(path: Path) -> dict[str, Any]:
    """The named fields of one file (or 3DUNDERWORLD folder); CalibrationError naming it where it
    is none of the containers above."""
    if path.is_dir():
        return _underworld_texts(path)
    if not path.is_file():
        raise CalibrationError(f"calibration file {path}: not found")
    suffix = path.suffix.lower()
    if suffix == ".json":
        try:
            document = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise CalibrationError(f"calibration file {path}: not JSON ({exc})") from None
        if not isinstance(document, dict):
            raise CalibrationError(f"calibration file {path}: not a JSON object of named fields")
        return {k: json_value(v) for k, v in document.items()}
    if suffix == ".mat":
        return _matlab(path)
    if suffix == ".txt":
        raise CalibrationError(
            f"calibration file {path}: a text file alone; give the folder holding 3DUNDERWORLD's "
            f"{', '.join(UNDERWORLD_TEXTS.values())}"
        )
    if suffix not in (".xml", ".yml", ".yaml"):
        raise CalibrationError(f"calibration file {path}: not .xml, .yml, .yaml, .json or .mat, nor a folder")
    return _file_storage(path)


def _file_storage(path: Path) -> dict[str, Any]:
    try:
        storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:  # OpenCV's parser error may come wrapped in a SystemError
        why = str(getattr(exc, "err", None) or exc.__cause__ or exc)
        if path.suffix.lower() == ".xml":
            raise CalibrationError(f"calibration file {path}: not an OpenCV FileStorage file ({why})") from None
        return _plain_yaml(path, why)  # Kalibr's and ROS's YAML are not OpenCV's
    try:
        if not storage.isOpened():
            raise CalibrationError(f"calibration file {path}: cannot be opened as OpenCV FileStorage")
        root = storage.root()
        names = root.keys()  # a FileNode's, not a dict's
        return {key: json_value(_node_value(root.getNode(key))) for key in names}  # ROS's {rows, cols, data}
    finally:
        storage.release()


def _plain_yaml(path: Path, why_not_opencv: str) -> dict[str, Any]:
    try:
        document = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise CalibrationError(
            f"calibration file {path}: neither OpenCV FileStorage ({why_not_opencv.strip()}) nor YAML ({exc})"
        ) from None
    if not isinstance(document, dict):
        raise CalibrationError(f"calibration file {path}: not a YAML map of named fields")
    return {str(k): json_value(v) for k, v in document.items()}


def _node_value(node: cv2.FileNode) -> Any:
    if node.isReal() or node.isInt():
        return node.real()
    if node.isString():
        return node.string()
    if node.isSeq():
        return [_node_value(node.at(i)) for i in range(node.size())]
    if node.isMap():
        names = node.keys()
        if {"dt", "data"} <= set(names):  # an OpenCV matrix, 2-D or n-D (mat() asserts on any other map)
            return node.mat()
        return {key: _node_value(node.getNode(key)) for key in names}
    return None


def json_value(value: Any) -> Any:
    """Matrices stored as {rows, cols, data} (OpenCV's JSON, ROS's camera_info) as arrays; maps
    within maps read so too."""
    if isinstance(value, dict) and {"rows", "cols", "data"} <= value.keys():
        try:
            return np.asarray(value["data"], dtype=np.float64).reshape(int(value["rows"]), int(value["cols"]))
        except (TypeError, ValueError):
            return value
    if isinstance(value, dict):
        return {str(k): json_value(v) for k, v in value.items()}
    return value


def _matlab(path: Path) -> dict[str, Any]:
    """A .mat file's variables (MATLAB's `save` of a struct, v7 or older), structs as dicts; a
    file holding one struct (`save f.mat s`) gives that struct's fields."""
    from scipy.io import loadmat  # only for .mat files: scipy's import is slow

    try:
        variables = loadmat(str(path), simplify_cells=True)
    except NotImplementedError:  # scipy says so for v7.3, which is HDF5
        raise CalibrationError(
            f"calibration file {path}: a MATLAB v7.3 (HDF5) file; save it with -v7 (save('f.mat', 's', '-v7'))"
        ) from None
    except (OSError, ValueError, TypeError) as exc:
        raise CalibrationError(f"calibration file {path}: not a MATLAB .mat file ({exc})") from None
    named = {k: _matlab_value(v) for k, v in variables.items() if not k.startswith("__")}
    if len(named) == 1 and isinstance(next(iter(named.values())), dict):
        return next(iter(named.values()))
    return named


def _matlab_value(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _matlab_value(v) for k, v in value.items()}
    if isinstance(value, np.ndarray) and value.dtype == object:  # MATLAB objects scipy cannot read
        return None
    if isinstance(value, str):
        return value
    if isinstance(value, np.ndarray | np.generic | bool | int | float):
        return np.asarray(value, dtype=np.float64) if np.asarray(value).dtype.kind in "biuf" else value
    return None


def _underworld_texts(folder: Path) -> dict[str, Any]:
    """3DUNDERWORLD's cam_matrix.txt, cam_distortion.txt, cam_rotation_matrix.txt and
    cam_trans_vectror.txt: numbers separated by tabs, one matrix row per line."""
    missing = [name for name in UNDERWORLD_TEXTS.values() if not (folder / name).is_file()]
    if missing:
        raise CalibrationError(
            f"calibration folder {folder}: not 3DUNDERWORLD's four text files (missing {', '.join(missing)})"
        )
    values: dict[str, Any] = {}
    for field, name in UNDERWORLD_TEXTS.items():
        try:
            rows = [[float(x) for x in line.split()] for line in (folder / name).read_text().splitlines()]
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise CalibrationError(f"calibration file {folder / name}: not rows of numbers ({exc})") from None
        rows = [row for row in rows if row]
        if not rows or len({len(row) for row in rows}) != 1:
            raise CalibrationError(f"calibration file {folder / name}: rows of unequal length or none")
        values[field] = np.asarray(rows, dtype=np.float64)
    return values
