"""The simulated bench: a physical model of projectors, cameras and a scene, with ground truth.

`SimBench` holds the scene and the device geometry; `SimProjector` and `SimCamera` implement the same
interfaces as real devices. Device geometry is given as objects with the `ViewModel` protocol
(rig.geometry.CameraModel satisfies it), so this package does not depend on `rig`.
"""

from drivers.sim.bench import GroundTruth, SimBench, SimCameraParams, SimProjectorParams, ViewModel
from drivers.sim.camera import SimCamera, SimCameraFaults
from drivers.sim.projector import SimProjector
from drivers.sim.scene import SceneObject, build_scene

__all__ = [
    "GroundTruth",
    "SceneObject",
    "SimBench",
    "SimCamera",
    "SimCameraFaults",
    "SimCameraParams",
    "SimProjector",
    "SimProjectorParams",
    "ViewModel",
    "build_scene",
]
