"""Accuracy against ground truth: every pair of a scan, and a merged cloud, measured on a rig
that has ground truth (the simulated bench)."""

from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "MIN_REGION_SHARE": "regions",
    "STEP_MM": "regions",
    "between_rings": "promise",
    "evaluate_merge": "merged",
    "evaluate_on_bench": "pairs",
    "footprints": "regions",
    "held_out_error": "holdout",
    "image_rows": "promise",
    "measure_on_bench": "merged",
    "pattern_economy": "surface",
    "region_errors": "regions",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "MIN_REGION_SHARE",
    "STEP_MM",
    "between_rings",
    "evaluate_merge",
    "evaluate_on_bench",
    "footprints",
    "held_out_error",
    "image_rows",
    "measure_on_bench",
    "pattern_economy",
    "region_errors",
]
