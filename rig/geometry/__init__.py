"""One geometric model for cameras and projectors, and triangulation."""

from rig.geometry.camera import CameraModel, look_at_rotation
from rig.geometry.triangulate import ray_plane, ray_ray_midpoint
from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "ConeHits": "cone",
    "SurfaceCurvature": "curvature",
    "affine_image": "cone",
    "closest_on_first_ray": "triangulate",
    "curve_curvature": "curvature",
    "parallel_projection": "ring_models",
    "principal_curvatures": "curvature",
    "radius_ratio": "ring_models",
    "ray_cone": "cone",
    "ray_half_plane": "cone",
    "refine_on_distorted_ring": "cone",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "CameraModel",
    "ConeHits",
    "SurfaceCurvature",
    "affine_image",
    "closest_on_first_ray",
    "curve_curvature",
    "look_at_rotation",
    "parallel_projection",
    "principal_curvatures",
    "radius_ratio",
    "ray_cone",
    "ray_half_plane",
    "ray_plane",
    "ray_ray_midpoint",
    "refine_on_distorted_ring",
]
