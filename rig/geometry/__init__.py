"""One geometric model for cameras and projectors, and triangulation."""

from rig.geometry.camera import CameraModel, look_at_rotation
from rig.geometry.triangulate import ray_plane, ray_ray_midpoint

__all__ = ["CameraModel", "look_at_rotation", "ray_plane", "ray_ray_midpoint"]
