"""Durable scan output: atomic files, PLY, depth PNG, preview, the scan directory."""

from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "DESCRIPTION_NAME": "scandir",
    "FrameSet": "frames",
    "TRUTH_ERRORS": "scandir",
    "check_image_size": "image_header",
    "depth_colour_jpeg": "images",
    "depth_image_png": "images",
    "frame_files": "frames",
    "image_header_bytes": "image_header",
    "json_problem": "portable",
    "load_pattern_spec": "frames",
    "natural_order": "frames",
    "new_scan_id": "scandir",
    "open_frames": "frames",
    "projector_view": "images",
    "publish_folder": "atomic",
    "publishing_through": "atomic",
    "read_cloud_ply": "ply",
    "read_frames": "frames",
    "read_image_header": "image_header",
    "read_mesh_ply": "ply",
    "read_mesh_vertices": "ply",
    "read_scan_frames": "scandir",
    "write_atomic": "atomic",
    "write_scan": "scandir",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "DESCRIPTION_NAME",
    "TRUTH_ERRORS",
    "FrameSet",
    "check_image_size",
    "depth_colour_jpeg",
    "depth_image_png",
    "frame_files",
    "image_header_bytes",
    "json_problem",
    "load_pattern_spec",
    "natural_order",
    "new_scan_id",
    "open_frames",
    "projector_view",
    "publish_folder",
    "publishing_through",
    "read_cloud_ply",
    "read_frames",
    "read_image_header",
    "read_mesh_ply",
    "read_mesh_vertices",
    "read_scan_frames",
    "write_atomic",
    "write_scan",
]
