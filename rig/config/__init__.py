"""Rig descriptions: YAML loaded into pydantic models, validated before any device opens.

Every model forbids unknown keys and bounds every number; lengths are millimetres (`_mm`),
times microseconds (`_us`) or seconds (`_s`), image sizes pixels. The drivers a config may name,
and what each can do, are the table in rig.config.drivers.
"""

from rig.config.calibration import BoardConfig, BoardPose, CalibrationConfig
from rig.config.drivers import DRIVERS, Capabilities, DeviceKind, DriverEntry, driver, drivers_of, named
from rig.config.equipment import CameraConfig, PowerConfig, ProjectorConfig
from rig.config.geometry import Geometry, Intrinsics, Pose
from rig.config.loading import DEFAULT_CONFIG, REPO_CONFIG_DIR, config_from_dict, load_config
from rig.config.rig import OutputConfig, RigConfig, ServiceConfig
from rig.config.scan import MergeConfig, ScanConfig
from rig.config.scenes import (
    SCENE_SHAPES,
    BlocksScene,
    BoxScene,
    CheckerTexture,
    GradientTexture,
    ImageTexture,
    MeshScene,
    PlaneScene,
    SceneShape,
    SimulationConfig,
    SphereOnPlaneScene,
    SphereScene,
    StepsScene,
    StripesTexture,
    TerrainScene,
    TextureConfig,
)
from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "ExposureUs": "scan",
    "RingPlanSettings": "scan",
    "Strict": "common",
    "validation_problems": "problems",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "DEFAULT_CONFIG",
    "DRIVERS",
    "REPO_CONFIG_DIR",
    "SCENE_SHAPES",
    "BlocksScene",
    "BoardConfig",
    "BoardPose",
    "BoxScene",
    "CalibrationConfig",
    "CameraConfig",
    "Capabilities",
    "CheckerTexture",
    "DeviceKind",
    "DriverEntry",
    "ExposureUs",
    "Geometry",
    "GradientTexture",
    "ImageTexture",
    "Intrinsics",
    "MergeConfig",
    "MeshScene",
    "OutputConfig",
    "PlaneScene",
    "Pose",
    "PowerConfig",
    "ProjectorConfig",
    "RigConfig",
    "RingPlanSettings",
    "ScanConfig",
    "SceneShape",
    "ServiceConfig",
    "SimulationConfig",
    "SphereOnPlaneScene",
    "SphereScene",
    "StepsScene",
    "Strict",
    "StripesTexture",
    "TerrainScene",
    "TextureConfig",
    "config_from_dict",
    "driver",
    "drivers_of",
    "load_config",
    "named",
    "validation_problems",
]
