"""Captures in other systems' conventions, made on the simulated bench, read back by `slrig
reconstruct`: every family of the pattern description against slrig's own codec of the same family,
and the time a folder takes against reading its PNG frames plus reconstructing them in memory.
Prints one JSON object; with --docs rewrites the foreign-roundtrip table in the manual (docs/).

    python bench/foreign_roundtrip.py [--docs]

Each family's patterns (rig.patterns.described.described_patterns) are projected on the default
bench (a diamond DMD's through its geometry, on a 1824x1140 virtual-pixel projector), captured,
saved as PNG files with the bench's true geometry as an OpenCV stereo calibration, and reconstructed
by reconstruct_folder; rms and coverage are measured against the simulator's ground truth through
the camera, as for slrig's own codec (gray; phase with the family's finest period and 8 steps; for
the diamond, square pixels of the same code density).
"""

from __future__ import annotations

import dataclasses
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # the tests' calibration writers

from _readme import markdown_table, run

from rig.assembly import open_rig
from rig.calibrate.foreign import ForeignCalibrationOptions, write_opencv_stereo
from rig.config import RigConfig, config_from_dict, load_config
from rig.patterns.described import described_patterns
from rig.patterns.diamond import virtual_image
from rig.patterns.phase import PhaseCodec, PhaseParams
from rig.patterns.spec import PatternSpec
from rig.pipeline.scan import run_scan
from rig.service.reconstruct import reconstruct_folder, reconstruct_frames
from rig.store.frames import read_frames
from tests import calibration_writers as writers


def _phase(periods: tuple[float, ...], unwrap: str, **more: Any) -> dict[str, Any]:
    return {"phase": {"frequencies": [{"period_px": p, "steps": 8} for p in periods], "unwrap": unwrap, **more}}


PROJECTOR = {"resolution": [1024, 768]}
MICRO = [16.0, 15.0, 15.1, 15.3, 18.4, 18.8, 19.5]  # micro phase shifting: the first N steps, the others once
FAMILIES: list[tuple[str, dict[str, Any], int | None]] = [  # name, description, own phase period (None: gray)
    ("Gray, OpenCV GrayCodePattern order", {"gray": {"axes": ["columns", "rows"], "white_black": "last"}}, None),
    (
        "binary, thresholds, LSB first",
        {"gray": {"code": "binary", "order": "lsb_first", "reference": "threshold", "white_black": "first"}},
        None,
    ),
    ("phase 16 px + Gray of periods", {**_phase((16,), "gray", shift="minus"), "gray": {"white_black": "first"}}, 16),
    ("heterodyne 16 / 17.5 / 19 px", _phase((16, 17.5, 19), "heterodyne", start_deg=90), 16),
    ("heterodyne 64 / 68 px", _phase((64, 68), "heterodyne"), 64),
    ("single-period cue 1024 / 128 / 16 px", _phase((1024, 128, 16), "hierarchical", shift="minus"), 16),
    (
        "a list per axis: cue 1100 / 16 px, rows 800 / 12 px",
        {"phase": {"axes": ["columns", "rows"], "unwrap": "hierarchical", "frequencies": {
            "columns": [{"period_px": 1100, "steps": 6}, {"period_px": 16, "steps": 8}],
            "rows": [{"period_px": 800, "steps": 6}, {"period_px": 12, "steps": 8}]}}},
        16,
    ),
    (
        "micro phase shifting: 16 px x 5, six periods 15-19.5 px once",
        {"phase": {"frequencies": [{"period_px": p, "steps": 5 if i == 0 else 1} for i, p in enumerate(MICRO)],
                   "unwrap": "micro"}},
        16,
    ),
    (
        "modulated phase shifting: cue 1100 / 16 px, carrier 6 px x 3",
        _phase((1100, 16), "hierarchical", modulation={"period_px": 6, "steps": 3}),
        16,
    ),
    ("one period, no unwrapping: 1100 / 800 px x 8", {"phase": {"axes": ["columns", "rows"], "unwrap": "none",
        "frequencies": {"columns": [{"period_px": 1100, "steps": 8}], "rows": [{"period_px": 800, "steps": 8}]}}}, 16),
]  # fmt: skip
DIAMOND: list[tuple[str, dict[str, Any]]] = [
    ("diamond DMD: Gray", {"gray": {"axes": ["columns", "rows"], "white_black": "first"}}),
    ("diamond DMD: cue 1824 / 152 / 24 px", _phase((1824, 152, 24), "hierarchical")),
    ("diamond DMD: Gray, sampled columns", {"gray": {"axes": ["columns", "rows"], "white_black": "first"}}),
]


def _error(grid: np.ndarray, camera: Any, truth: Any, in_camera_frame: bool) -> tuple[float, int]:
    points = (grid - camera.t) @ camera.R if in_camera_frame else grid
    ok = np.isfinite(points).all(axis=2) & truth.hit
    return float(np.sqrt(np.mean(np.sum((points[ok] - truth.points[ok]) ** 2, axis=1)))), int(ok.sum())


def _render(rig: Any, spec: PatternSpec, folder: Path, diamond: bool = False) -> Path:
    folder.mkdir(parents=True)
    for i, pattern in enumerate(described_patterns(spec)):
        rig.projectors[0].show(virtual_image(pattern) if diamond else pattern)
        cv2.imwrite(str(folder / f"frame_{i:02d}.png"), rig.cameras[0].capture().image)
    (folder / "patterns.yaml").write_text(yaml.safe_dump(spec.model_dump(mode="json")))
    return folder


def _reconstructed(
    folder: Path, calibration: Path | list[Path], config: RigConfig, camera: Any, truth: Any, projector: Any = None,
    options: ForeignCalibrationOptions | None = None,
) -> dict[str, Any]:  # fmt: skip
    """The folder reconstructed: frames, rms (mm) and pixels against the truth, seconds, and (with the
    projector's true model) the decoded coordinates' median and p95 distance from the true ones (px)."""
    t0 = time.perf_counter()
    _, result = reconstruct_folder(
        folder, folder / "patterns.yaml", calibration, Path(tempfile.mkdtemp(dir=folder.parent)) / "scan", "x", config,
        options,
    )  # fmt: skip
    seconds = time.perf_counter() - t0
    rms, covered = _error(result.pairs[0].grid, camera, truth, in_camera_frame=True)
    row = {"frames": result.frames_projected, "rms_mm": rms, "pixels": covered, "reconstruct_s": round(seconds, 2)}
    if projector is not None:
        found = result.pairs[0].correspondence
        seen = found.valid & truth.hit
        true_uv = projector.project(truth.points[seen])[0]
        off = [np.abs(c[seen] - true_uv[:, i]) for i, c in enumerate((found.u, found.v)) if c is not None]
        distance = np.concatenate(off)
        row |= {
            "median_px": round(float(np.median(distance)), 4),
            "p95_px": round(float(np.percentile(distance, 95)), 3),
        }
    row["points"] = result.pairs[0].grid
    return row


def _with_projector(config: RigConfig, **changes: Any) -> RigConfig:
    data = config.model_dump(mode="json")
    for key, value in changes.items():
        if key == "phase":
            data["scan"]["phase"] = value
        else:
            data["projectors"][0][key] = value
    return config_from_dict(data, "foreign round trip")


def _families(scratch: Path) -> list[dict[str, Any]]:
    config = load_config()
    rows, own = [], {}
    with open_rig(config) as rig:
        assert rig.truth is not None
        truth = rig.truth.ground_truth(0, 0)
        camera, projector = rig.camera_models[0], rig.projector_models[0]
        calibration = write_opencv_stereo(scratch / "bench.xml", camera, projector)
        own["gray"] = _error(run_scan(rig, "gray").pairs[0].grid, camera, truth, False)
        own[16] = _error(run_scan(rig, "phase").pairs[0].grid, camera, truth, False)
        codec = PhaseCodec((1024, 768), PhaseParams(steps=8, period_px=16))
        described = [*FAMILIES, ("phase 16 px, slrig's own description", codec.description().model_dump(), 16)]
        folders = []
        for k, (name, block, period) in enumerate(described):
            spec = PatternSpec.model_validate({"projector": PROJECTOR, **block})
            folders.append((name, period, _render(rig, spec, scratch / f"family{k}")))
    with open_rig(_with_projector(config, phase={"steps": 8, "period_px": 64})) as rig:
        own[64] = _error(run_scan(rig, "phase").pairs[0].grid, camera, truth, False)
    for name, period, folder in folders:
        row = {"family": name, **_reconstructed(folder, calibration, config, camera, truth, projector)}
        row.pop("points")
        reference = own["gray" if period is None else period]
        row |= {"own": "gray" if period is None else f"phase {period} px", "own_rms_mm": reference[0]}
        row["own_pixels"] = reference[1]
        rows.append(row)
    return rows


def _diamond(scratch: Path) -> list[dict[str, Any]]:
    """Each diamond family beside square pixels of the same code density; the sampled-column
    convention with the calibration that convention makes (the projector's cx half a column less)."""
    intrinsics = {"fx": 2670.0, "fy": 2670.0, "cx": 911.5, "cy": 569.5}
    base = load_config()
    geometry = {**base.model_dump(mode="json")["projectors"][0]["geometry"], "intrinsics": intrinsics}
    config = _with_projector(base, resolution=[1824, 1140], geometry=geometry)
    rows, made = [], []
    with open_rig(config) as rig:
        assert rig.truth is not None
        truth = rig.truth.ground_truth(0, 0)
        camera, projector = rig.camera_models[0], rig.projector_models[0]
        sampled = dataclasses.replace(projector, K=projector.K - np.array([[0, 0, 0.5], [0, 0, 0], [0, 0, 0]]))
        calibrations = {
            "mirror_centre": (write_opencv_stereo(scratch / "diamond.xml", camera, projector), projector),
            "sampled": (write_opencv_stereo(scratch / "diamond_sampled.xml", camera, sampled), sampled),
        }
        for k, (name, block) in enumerate(DIAMOND):
            convention = "sampled" if "sampled" in name else "mirror_centre"
            specs = {
                kind: PatternSpec.model_validate(
                    {
                        "projector": {
                            "resolution": [1824, 1140],
                            "pixel_geometry": kind,
                            "code_step_px": step,
                            **({"diamond_column": convention} if kind == "diamond" else {}),
                        },
                        **block,
                    }
                )
                for kind, step in (("diamond", 1), ("square", 2))
            }
            folders = {g: _render(rig, spec, scratch / f"diamond{k}_{g}", g == "diamond") for g, spec in specs.items()}
            made.append((name, convention, folders))
    for name, convention, folders in made:
        calibration, model = calibrations[convention]
        row = {"family": name, **_reconstructed(folders["diamond"], calibration, config, camera, truth, model)}
        twin = _reconstructed(folders["square"], calibrations["mirror_centre"][0], config, camera, truth)
        row.pop("points")
        rows.append(
            row | {"own": "square pixels, same density", "own_rms_mm": twin["rms_mm"], "own_pixels": twin["pixels"]}
        )
    return rows


def _readers(scratch: Path, folder: Path) -> list[dict[str, Any]]:
    """The bench's true geometry written as each tool writes its calibration, read back, and the Gray
    family's folder reconstructed through it: every point against the reference file's."""
    config = load_config()
    with open_rig(config) as rig:
        assert rig.truth is not None
        truth = rig.truth.ground_truth(0, 0)
        camera, projector = rig.camera_models[0], rig.projector_models[0]
    rotation = projector.R @ camera.R.T
    pair = writers.Pair(
        camera.K, _five(camera.dist), (camera.width, camera.height), projector.K, _five(projector.dist),
        (projector.width, projector.height), rotation, projector.t - rotation @ camera.t,
    )  # fmt: skip
    sizes = ForeignCalibrationOptions(camera_resolution=pair.camera_size, projector_resolution=pair.projector_size)
    reference = _reconstructed(folder, scratch / "bench.xml", config, camera, truth)
    rows = []
    for k, (name, write) in enumerate(writers.WRITERS.items()):
        (scratch / f"format{k}").mkdir()
        files = write(scratch / f"format{k}", pair)
        row = _reconstructed(folder, files, config, camera, truth, options=sizes)
        points = row.pop("points")
        same = np.isfinite(points).all(axis=2) & np.isfinite(reference["points"]).all(axis=2)
        moved = np.linalg.norm(points[same] - reference["points"][same], axis=1)
        rows.append({
            "format": name, "files": ", ".join(f.name for f in files), "rms_mm": round(row["rms_mm"], 4),
            "pixels": row["pixels"], "largest_move_mm": float(f"{moved.max():.2g}"),
        })  # fmt: skip
    return rows


def _five(dist: np.ndarray) -> np.ndarray:
    out = np.zeros(5)
    out[: min(5, np.size(dist))] = np.ravel(dist)[:5]
    return out


def _speed(folder: Path, calibration: Path, config: RigConfig, repeats: int = 7) -> dict[str, Any]:
    """A folder's reconstruction against reading its frames plus reconstructing them in memory:
    one run untimed (caches), then `repeats` of each, in alternating order, medians and ranges."""
    spec = PatternSpec.model_validate(yaml.safe_load((folder / "patterns.yaml").read_text()))
    options = ForeignCalibrationOptions()
    times: dict[str, list[float]] = {"read": [], "memory": [], "folder": []}

    def separately(k: int) -> None:
        t0 = time.perf_counter()
        frames = read_frames(folder, spec.frames, len(spec.roles()))
        t1 = time.perf_counter()
        reconstruct_frames(frames, spec, calibration, folder.parent / f"mem{k}", "x", config, options, {})
        times["read"].append(t1 - t0)
        times["memory"].append(time.perf_counter() - t1)

    def whole(k: int) -> None:
        t0 = time.perf_counter()
        reconstruct_folder(folder, folder / "patterns.yaml", calibration, folder.parent / f"all{k}", "x", config)
        times["folder"].append(time.perf_counter() - t0)

    whole(-1)
    times["folder"].clear()
    for k in range(repeats):
        for step in (separately, whole) if k % 2 else (whole, separately):
            step(k)
    frames = read_frames(folder, spec.frames, len(spec.roles()))
    height, width = frames.frames[0].shape
    out: dict[str, Any] = {"frames": len(frames.frames), "size": [width, height], "repeats": repeats}
    for name, key in (("read", "png_read_s"), ("memory", "in_memory_s"), ("folder", "folder_s")):
        out[key] = round(statistics.median(times[name]), 3)
        out[key.replace("_s", "_range_s")] = [round(min(times[name]), 3), round(max(times[name]), 3)]
    return out


def measure() -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        rows = _families(root) + _diamond(root)
        readers = _readers(root, root / "family0")
        cue = next(root / f"family{k}" for k, (name, _, _) in enumerate(FAMILIES) if name.startswith("single"))
        speed = _speed(cue, root / "bench.xml", load_config())
    for row in rows:
        row["rms_ratio"] = round(row["rms_mm"] / row["own_rms_mm"], 3)
        row["rms_mm"], row["own_rms_mm"] = round(row["rms_mm"], 4), round(row["own_rms_mm"], 4)
    return {"benchmark": "foreign_roundtrip", "families": rows, "readers": readers, "speed": speed}


def table(report: dict[str, Any]) -> str:
    header = ["family", "frames", "rms mm", "pixels", "median px", "p95 px", "slrig's own", "its rms mm", "ratio", "s"]
    rows = [
        [
            r["family"], r["frames"], r["rms_mm"], r["pixels"], r["median_px"], r["p95_px"], r["own"],
            r["own_rms_mm"], r["rms_ratio"], r["reconstruct_s"],
        ]
        for r in report["families"]
    ]  # fmt: skip
    readers = [[r["format"], r["files"], r["rms_mm"], r["pixels"], r["largest_move_mm"]] for r in report["readers"]]
    s = report["speed"]
    return (
        markdown_table(header, rows)
        + "\n\n(median and p95 px: how far the decoded projector coordinates lie from the true ones, over every "
        "pixel decoded where the bench's camera sees a surface, depth edges and their blur included.)\n\n"
        "**Every calibration reader**: the bench's true geometry written as each tool writes it, read back, and "
        "the Gray family's folder reconstructed through it, against the same folder through the OpenCV stereo "
        "file above:\n\n"
        + markdown_table(["format", "files", "rms mm", "pixels", "largest move of a point, mm"], readers)
        + f"\n\nA folder of {s['frames']} PNG frames at {s['size'][0]}x{s['size'][1]} (the cue family), medians "
        f"of {s['repeats']} runs: {s['folder_s']} s for `reconstruct` (range {s['folder_range_s'][0]}-"
        f"{s['folder_range_s'][1]}), against {s['png_read_s']} s to read the PNG files and {s['in_memory_s']} s "
        f"(range {s['in_memory_range_s'][0]}-{s['in_memory_range_s'][1]}) to reconstruct them from memory "
        "(decode, triangulate, write the scan).\n\n"
        "Measured by `python bench/foreign_roundtrip.py --docs`."
    )


if __name__ == "__main__":
    run(__doc__ or "", "foreign-roundtrip", measure, table)
