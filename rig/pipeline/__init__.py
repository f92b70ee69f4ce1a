"""The scan pipeline: capture (show, sync, take frames), decode through a codec, triangulate
(dense grids or ring samples), and merge the pairs of a rig into one cloud. It works on an open
Rig and knows nothing of storage, jobs or the web."""

from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "CUE": "capture",
    "Interpolant": "surface",
    "LiveFrame": "live",
    "LiveStats": "live",
    "MaskSkew": "mask_skew",
    "Mesh": "mesh",
    "PairResult": "results",
    "PointSet": "pointset",
    "RingBands": "surface",
    "RingSurface": "surface",
    "ScanResult": "results",
    "SurfaceSettings": "surface_settings",
    "interpolate_surface": "surface",
    "live_codecs": "live",
    "moved_pair": "realign",
    "precision_recall": "overlap",
    "reconstruct_exposures": "hdr",
    "reconstruct_frames": "scan",
    "reconstruct_pair": "scan",
    "ring_bands": "scan",
    "ring_lit": "scan",
    "run_live": "live",
    "run_scan": "scan",
    "sampling_distance": "merge",
    "scan_with_exposure": "hdr",
    "surface_holes": "holes",
    "texture_rgb": "dense",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "CUE",
    "Interpolant",
    "LiveFrame",
    "LiveStats",
    "MaskSkew",
    "Mesh",
    "PairResult",
    "PointSet",
    "RingBands",
    "RingSurface",
    "ScanResult",
    "SurfaceSettings",
    "interpolate_surface",
    "live_codecs",
    "moved_pair",
    "precision_recall",
    "reconstruct_exposures",
    "reconstruct_frames",
    "reconstruct_pair",
    "ring_bands",
    "ring_lit",
    "run_live",
    "run_scan",
    "sampling_distance",
    "scan_with_exposure",
    "surface_holes",
    "texture_rgb",
]
