"""What each top-level key of a scan's manifest.json holds: the manual's reference (docs/reference)
is written from this, and a test holds it to what rig.store.scandir.write_scan writes."""

from __future__ import annotations

MANIFEST_FIELDS: dict[str, str] = {
    "scan_id": "the scan's id (YYYYMMDD-HHMMSS-xxxxxx), also its folder's name under <data_dir>/scans",
    "origin": "where it came from: {captured: true}, {reprocessed_from: ID, calibration}, or "
    "{reconstructed: {frames_sha256, patterns, calibration ..., warnings}} for another system's frames (warnings: what "
    "its decode says of the pattern description, with numbers)",
    "status": "done (a scan is written whole through <id>.partial, or not at all)",
    "created_utc": "when it was written, ISO 8601 in UTC",
    "software": "the versions of slrig, Python, NumPy and OpenCV that made it",
    "codec": "{name, params}: the pattern codec and its parameters",
    "devices": "{projectors, cameras}: each device's name, driver and resolution; cameras also their bit "
    "depth and the exposure (us) they actually had",
    "calibration_sha256": "the calibration file's hash (a 16-hex prefix), or null when the config's own "
    "geometry was used",
    "response_sha256": "the projector response file's hash (16-hex prefix), or null",
    "economy": "{frames_projected, frames_captured, bytes_captured, points}: what the scan cost",
    "pairs": "one entry per projector-camera pair: projector, camera, points, the decoder's counts (lit, "
    "decoded, ...), and ring_coverage for ring scans",
    "surface": "ring scans: the surface between the rings (interpolant, mesh_vertices, mesh_faces, pixels) and, "
    "per pair, its holes: where the rings promise a surface and it has none (count, total area, the largest)",
    "adaptive": "adaptive or planned scans: the ring plan (with its pilot's signature), its tolerance and "
    "quantile, whether the pilot ran, the economy beside the pilot's, how far the ring points lie from the "
    "plan's pilot (pilot_agreement_mm), the surface judged by leaving out every other ring "
    "(held_out_ring_p95_mm), and `check`: the tolerance promised beside what is known of it (tolerance: "
    "measured against the truth, bounded by the held-out rings, rehearsed, or unverified)",
    "exposure": "auto-exposure or HDR scans: the mode, each camera's exposures (us; HDR: one per pass) and, per "
    "camera, each pre-capture's look: its exposure, the shares of lit and clipped pixels, white-frame quantiles",
    "timings_ms": "milliseconds per step (capture_ms, decode_ms, triangulate_ms, pointset_ms, ...)",
    "merge": "several pairs: how their clouds were merged (overlap removed, points kept), else null",
    "metrics": "simulated rigs: accuracy against the ground truth per pair (rms_mm, p95_mm, completeness, "
    "...) and merged; empty on a real rig",
    "files": "the files the scan wrote, by role: cloud, preview, depth (per camera), mesh, frames (per "
    "pair, when kept), truth_errors (simulated rigs)",
    "config": "the whole rig description it was made with (geometry, codec, filters), so it can be "
    "reprocessed with `slrig reconstruct SCAN_DIR`",
}
