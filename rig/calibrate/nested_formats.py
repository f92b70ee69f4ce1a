"""Formats whose devices are maps within the file (Kalibr's camchain, MATLAB's stereoParameters
struct), flattened into named fields (`cam0.intrinsics`, `CameraParameters1.K`) in OpenCV's
conventions, so that the one reader (rig.calibrate.foreign) checks them like any other file."""

from __future__ import annotations

from typing import Any

import numpy as np


def flattened(values: dict[str, Any]) -> dict[str, Any]:
    """The values with a Kalibr camchain's or a MATLAB struct's devices flattened; ValueError
    naming the field where one cannot be read as slrig's models."""
    return matlab_fields(kalibr_fields(values))


def kalibr_fields(values: dict[str, Any]) -> dict[str, Any]:
    """A Kalibr camchain's cam0 and cam1 as flat fields (`cam0.intrinsics` as a 3x3 matrix,
    `cam1.T_cn_cnm1.R` and `.t`); the values as they are for any other file. ValueError naming the
    field where a camera is not a pinhole with radtan (or no) distortion."""
    cameras = [values.get(name) for name in ("cam0", "cam1")]
    if not all(isinstance(c, dict) and "intrinsics" in c for c in cameras):
        return values
    flat: dict[str, Any] = {k: v for k, v in values.items() if k not in ("cam0", "cam1")}
    for name, camera in zip(("cam0", "cam1"), cameras, strict=True):
        assert isinstance(camera, dict)
        if camera.get("camera_model", "pinhole") != "pinhole":
            raise ValueError(f"{name}.camera_model: {camera['camera_model']}; slrig's devices are pinholes")
        if camera.get("distortion_model", "radtan") not in ("radtan", "none"):
            raise ValueError(f"{name}.distortion_model: {camera['distortion_model']}; slrig models radtan only")
        intrinsics = camera["intrinsics"]
        if not isinstance(intrinsics, list | tuple) or len(intrinsics) != 4:
            raise ValueError(f"{name}.intrinsics: not [fu fv pu pv]")
        fu, fv, pu, pv = (float(x) for x in intrinsics)
        flat[f"{name}.intrinsics"] = [[fu, 0.0, pu], [0.0, fv, pv], [0.0, 0.0, 1.0]]
        for key in ("distortion_coeffs", "resolution"):
            if key in camera:
                flat[f"{name}.{key}"] = camera[key]
    pose = cameras[1].get("T_cn_cnm1") if isinstance(cameras[1], dict) else None
    if pose is not None:
        rows = [list(row) for row in pose] if isinstance(pose, list | tuple) else pose
        flat["cam1.T_cn_cnm1.R"] = [row[:3] for row in rows[:3]]
        flat["cam1.T_cn_cnm1.t"] = [row[3] for row in rows[:3]]
    return flat


def matlab_fields(values: dict[str, Any]) -> dict[str, Any]:
    """MATLAB's stereoParameters struct (`CameraParameters1`, `CameraParameters2`, the pose of
    camera 2) as flat fields in OpenCV's conventions; the values as they are for any other file."""
    cameras = [values.get(name) for name in ("CameraParameters1", "CameraParameters2")]
    if not all(isinstance(c, dict) and "ImageSize" in c for c in cameras):
        return values
    flat = {k: v for k, v in values.items() if k not in ("CameraParameters1", "CameraParameters2", "PoseCamera2")}
    for name, camera in zip(("CameraParameters1", "CameraParameters2"), cameras, strict=True):
        assert isinstance(camera, dict)
        flat[f"{name}.K"] = _matlab_k(name, camera)
        flat[f"{name}.RadialDistortion+TangentialDistortion"] = _matlab_distortion(name, camera)
        flat[f"{name}.ImageSize"] = camera["ImageSize"]
        if "WorldUnits" in camera:
            flat[f"{name}.WorldUnits"] = camera["WorldUnits"]
    rotation = values.get("RotationOfCamera2")
    if rotation is not None:  # x2 = x1 R + t with row vectors: OpenCV's R is its transpose
        flat.pop("RotationOfCamera2")
        flat["RotationOfCamera2'"] = np.asarray(rotation, dtype=np.float64).reshape(3, 3).T
    pose = values.get("PoseCamera2")
    if rotation is None and isinstance(pose, dict) and {"R", "Translation"} <= pose.keys():
        r = np.asarray(pose["R"], dtype=np.float64).reshape(3, 3)  # camera 2 to camera 1: invert it
        flat["PoseCamera2.R'"] = r.T
        flat["-PoseCamera2.R' Translation"] = -r.T @ np.asarray(pose["Translation"], dtype=np.float64).ravel()
    return flat


def _matlab_k(name: str, camera: dict[str, Any]) -> np.ndarray:
    if "K" in camera:
        k = np.array(camera["K"], dtype=np.float64).reshape(3, 3)
    elif "IntrinsicMatrix" in camera:  # before R2022b: [fx 0 0; s fy 0; cx cy 1], K's transpose
        k = np.array(camera["IntrinsicMatrix"], dtype=np.float64).reshape(3, 3).T
    else:
        raise ValueError(f"{name}: neither K nor IntrinsicMatrix")
    k[0, 2] -= 1.0  # MATLAB's first pixel's centre is (1, 1), OpenCV's (0, 0)
    k[1, 2] -= 1.0
    return k


def _matlab_distortion(name: str, camera: dict[str, Any]) -> np.ndarray:
    radial = np.atleast_1d(np.asarray(camera.get("RadialDistortion", [0.0, 0.0]), dtype=np.float64)).ravel()
    tangential = np.atleast_1d(np.asarray(camera.get("TangentialDistortion", [0.0, 0.0]), dtype=np.float64)).ravel()
    if radial.size not in (2, 3) or tangential.size != 2:
        raise ValueError(
            f"{name}: RadialDistortion of {radial.size} and TangentialDistortion of {tangential.size} values; "
            "MATLAB's are 2 or 3 and 2"
        )
    k3 = radial[2] if radial.size == 3 else 0.0
    return np.array([radial[0], radial[1], tangential[0], tangential[1], k3])
