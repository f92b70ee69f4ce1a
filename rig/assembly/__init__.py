"""Rig assembly: a config's devices built through the driver table (rig.config.drivers), in the
real world or on the simulated bench, into an open Rig."""

from rig.assembly.build import geometry_model, open_rig, rig_geometry
from rig.assembly.world import World
from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "CAMERA_BYTES_PER_PIXEL": "memory",
    "FIXED_BYTES": "memory",
    "available_memory": "memory",
    "build_scene": "simulated",
    "check_memory": "memory",
    "frame_sample_bytes": "memory",
    "frames_per_scan": "memory",
    "scan_memory": "memory",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "CAMERA_BYTES_PER_PIXEL",
    "FIXED_BYTES",
    "World",
    "available_memory",
    "build_scene",
    "check_memory",
    "frame_sample_bytes",
    "frames_per_scan",
    "geometry_model",
    "open_rig",
    "rig_geometry",
    "scan_memory",
]
