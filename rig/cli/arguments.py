"""The `slrig` command line: its arguments, one builder per command."""

from __future__ import annotations

import argparse
from pathlib import Path

from rig import __version__
from rig.cli.batch_arguments import batch_command
from rig.config import SCENE_SHAPES
from rig.patterns import codec_names

MESH_FIT_SIZE_MM = 150.0


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        help="rig description (YAML); default: the simulated bench, config/sim.yaml",
    )
    p.add_argument("--codec", default=None, help=f"pattern codec: {', '.join(codec_names())} (default: the config's)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _exposure(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--exposure",
        default=None,
        help="auto (from a white and a black pre-capture), camera (each camera's own), or microseconds "
        "(scan.exposure.exposure)",
    )
    p.add_argument(
        "--hdr",
        default=None,
        help="capture at several exposures, merged per pixel: auto, a count, or microseconds as US,US,... "
        "(scan.exposure.hdr)",
    )
    p.add_argument(
        "--adaptive-projection",
        action="store_true",
        help="dim the patterns where the camera would clip, from a pre-scan, so one exposure reads dark and "
        "shiny alike (scan.exposure.adaptive_projection; not --adaptive, which plans rings)",
    )


def _scan_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    scan = sub.add_parser("scan", help="scan and write a scan directory (cloud.ply, depth, preview)")
    _common(scan)
    _exposure(scan)
    scan.add_argument(
        "--out",
        type=Path,
        default=None,
        help="scan directory to create (must not exist); default <data_dir>/scans/<id>",
    )
    scan.add_argument(
        "--adaptive", action="store_true", help="pilot scan, ring plan from its curvature, then the planned rings"
    )
    scan.add_argument(
        "--tolerance-mm",
        type=float,
        default=None,
        help="--adaptive: the surface within this of the object (scan.adaptive; on --tolerance-quantile of the area)",
    )
    scan.add_argument(
        "--tolerance-quantile",
        type=float,
        default=None,
        help="--adaptive: the share of every surface region's area within the tolerance (0.95)",
    )
    scan.add_argument(
        "--save-frames",
        action="store_true",
        help="keep the camera frames in the scan directory (as scan.save_frames), to reprocess them later with "
        "`slrig reconstruct SCAN_DIR`",
    )
    scan.add_argument("--plan", type=Path, default=None, help="scan the rings of this plan file (no pilot)")
    scan.add_argument("--save-plan", type=Path, default=None, help="--adaptive: also write the plan to this file")


def _live_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    live = sub.add_parser(
        "live", help="repeat a short sequence and report a depth image per sequence (clouds/s, latency)"
    )
    _common(live)
    live.add_argument("--seconds", type=float, default=None, help="stop after this long (default: at Ctrl-C)")
    live.add_argument(
        "--hdr",
        default=None,
        help="every sequence at several exposures, merged per pixel: auto (bracketed once at the start) or "
        "2 to 4 microsecond values as US,US (scan.live.hdr)",
    )
    live.add_argument("--depth-png", type=Path, default=None, help="write the last sequence's depth (camera 0) here")


def _evaluate_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    evaluate = sub.add_parser("eval", help="scan the simulated bench and measure it against ground truth")
    _common(evaluate)
    _exposure(evaluate)
    evaluate.add_argument(
        "--scene",
        default=None,
        help=f"scene name ({', '.join(k for k in SCENE_SHAPES if k != 'mesh')}) or a "
        f"PLY/OBJ/STL file (scaled to {MESH_FIT_SIZE_MM:.0f} mm)",
    )


def _plan_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    plan = sub.add_parser(
        "plan", help="views: the fewest projector-camera heads that cover an object; rings: the fewest rings"
    )
    plan.add_argument("what", choices=["views", "rings"])
    plan.add_argument(
        "--from",
        dest="source",
        type=Path,
        nargs="+",
        default=None,
        help="rings: plan from these scan directories (several: one plan for a kind of object)",
    )
    plan.add_argument(
        "--tolerance-mm", type=float, default=None, help="rings: the surface within this of the object (0.2)"
    )
    plan.add_argument(
        "--tolerance-quantile", type=float, default=None, help="rings: on this share of every region's area (0.95)"
    )
    plan.add_argument("--out", type=Path, default=None, help="rings: write the plan to this file (JSON)")
    plan.add_argument("--config", type=Path, default=None, help="rig description (YAML); default: config/sim.yaml")
    plan.add_argument("--scene", default=None, help="box, sphere or a mesh file (default: the config's object)")
    plan.add_argument("--coverage", type=float, default=0.95, help="fraction of the surface to cover (0.95)")
    plan.add_argument("--candidates", type=int, default=120, help="candidate heads on a sphere (120)")
    plan.add_argument("--poses", type=Path, default=None, help="YAML list of candidate camera positions [x, y, z] mm")
    plan.add_argument("--distance", type=float, default=None, help="their distance, mm (4 x the object's radius)")
    plan.add_argument("--max-angle", type=float, default=65.0, help="steepest view of a surface, degrees (65)")
    plan.add_argument("--baseline", type=float, default=15.0, help="projector beside camera, degrees (15)")
    plan.add_argument("--min-elevation", type=float, default=-90.0, help="lowest head, degrees (-90: all round)")
    plan.add_argument("--confirm", action="store_true", help="render the plan on the simulated bench and measure it")
    plan.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _serve_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    serve = sub.add_parser("serve", help="run the daemon: REST API (under /v1) and job queue for this rig")
    serve.add_argument("--config", type=Path, default=None, help="rig description (YAML); default: config/sim.yaml")
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    serve.add_argument("--port", type=int, default=8750, help="TCP port (default 8750; 0: any free port)")
    serve.add_argument("--api-key-file", type=Path, default=None, help="file holding the API key (else $SLRIG_API_KEY)")
    serve.add_argument(
        "--read-key-file",
        type=Path,
        default=None,
        help="file holding a read-only key, for dashboards that only watch (else $SLRIG_READ_KEY; optional)",
    )


def _devices_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    devices = sub.add_parser("devices", help="list attached USB devices, video nodes, serial ports and OAK cameras")
    devices.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _doctor_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    doctor = sub.add_parser("doctor", help="check a rig config against this machine; --latency measures displays")
    doctor.add_argument("--config", type=Path, default=None, help="rig description (YAML); default: config/sim.yaml")
    doctor.add_argument(
        "--latency",
        action="store_true",
        help="measure each projector's display-to-capture latency and store it in <data_dir>",
    )
    doctor.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _cal_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    cal = sub.add_parser("calibrate", help="calibrate cameras, projectors, or the whole rig into one world frame")
    cal.add_argument(
        "what",
        choices=["camera", "projector", "rig", "response"],
        help="camera: the cameras; projector or rig: cameras and projectors (a projector is "
        "calibrated against a camera); response: each projector's response (gamma)",
    )
    cal.add_argument("--config", type=Path, default=None, help="rig description (YAML); default: config/sim.yaml")
    cal.add_argument("--views", type=int, default=None, help="board poses to capture on the simulated bench")
    cal.add_argument(
        "--images",
        type=Path,
        default=None,
        help="read the views from this folder (view_NN/<camera>.png, view_NN/<projector>_<camera>/)",
    )
    cal.add_argument(
        "--patterns",
        type=Path,
        default=None,
        help="with --images: another system's captures, one sub-folder per board pose, its frames as this "
        "pattern description (YAML) lists them; no device is opened",
    )
    cal.add_argument("--view-glob", default="*", help="with --patterns: the sub-folders that are views (capture_*)")
    cal.add_argument(
        "--board-image",
        choices=["auto", "white", "mean", "modulation"],
        default="auto",
        help="with --patterns: where the board is found (auto: the white frame, else the frames' mean)",
    )
    cal.add_argument(
        "--board",
        default=None,
        help="the board as KIND:COLSxROWS:SQUARE_MM[:MARKER_MM[:DICTIONARY]] (squares, not inner corners), e.g. "
        "checker:10x8:75 or charuco:11x8:30:22:DICT_5X5_100; default: the config's calibration.board",
    )
    cal.add_argument(
        "--model",
        default=None,
        help="lens model: auto (drop what the views do not determine), or k1, k1k2, k1k2_tangential, full with "
        "+fixed_centre and/or +fixed_aspect (k1k2+fixed_aspect); default: the config's calibration.model",
    )
    cal.add_argument("--camera-model", default=None, help="the cameras' lens model (as --model); default: --model's")
    frames = "board (the first view's board, z = 0 its plane; the simulated bench's) or camera (the first camera's)"
    cal.add_argument("--world", choices=["board", "camera"], help=f"the calibration's frame: {frames}; default: board")
    cal.add_argument(
        "--projector-model", default=None, help="the projectors' lens model (as --model); default: --model's"
    )
    cal.add_argument("--save-views", type=Path, default=None, help="also write the captured views to this folder")
    cal.add_argument(
        "--out",
        type=Path,
        default=None,
        help="folder for calibration.json/.yaml and coverage pictures; default <data_dir>/calibration",
    )
    cal.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _recognition_commands(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    gallery = sub.add_parser("gallery", help="the recognition gallery: labelled scans to identify others against")
    action = gallery.add_subparsers(dest="action", required=True)
    add = action.add_parser("add", help="describe a scan directory and add it under a label")
    add.add_argument("scan_dir", type=Path)
    add.add_argument("--label", required=True, help="a plain name: letters, digits, '.', '_', '-'")
    sizes = (("rings", int, 8), ("samples", int, 64), ("inner-mm", float, 6), ("outer-mm", float, 48))
    for name, kind, default in sizes:
        add.add_argument(f"--{name}", type=kind, default=None, help=f"descriptor (first entry only; default {default})")
    add.add_argument("--distance", choices=["geodesic", "euclidean"], default=None, help="descriptor (geodesic)")
    add.add_argument("--spectrum", choices=["per_ring", "concatenated"], default=None, help="descriptor (per_ring)")
    add.add_argument("--frame", choices=["balanced", "viewer"], default=None, help="descriptor (balanced)")
    lister = action.add_parser("list", help="the gallery's entries")
    remove = action.add_parser("remove", help="remove an entry by its id")
    remove.add_argument("entry_id", type=int)
    identify = sub.add_parser("identify", help="identify a scan directory against the gallery")
    identify.add_argument("scan_dir", type=Path)
    identify.add_argument("--top", type=int, default=5, help="labels to list (5)")
    identify.add_argument(
        "--threshold",
        type=float,
        default=None,
        help="below this score: unknown (default: per comparison, from the recognition benchmark's EER)",
    )
    identify.add_argument("--raw", action="store_true", help="the published comparison: raw correlation")
    for p in (add, lister, remove, identify):
        p.add_argument("--config", type=Path, default=None, help="rig description; the gallery is in its data_dir")
        p.add_argument("--gallery", type=Path, default=None, help="gallery file (default <data_dir>/gallery.db)")
        p.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _size(text: str) -> tuple[int, int]:
    """WIDTHxHEIGHT."""
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT") from None
    return width, height


def _reconstruct_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    rec = sub.add_parser(
        "reconstruct",
        help="a scan directory from frames on disk (no devices): a scan's own (--save-frames), or another system's",
    )
    rec.add_argument(
        "frames_dir",
        type=Path,
        help="a scan directory that kept its frames (its patterns, rig and calibration are in its manifest), "
        "or a folder of another system's frames",
    )
    rec.add_argument(
        "--patterns",
        type=Path,
        default=None,
        help="the pattern description (YAML) of the frames; default: patterns.yaml in the folder",
    )
    rec.add_argument(
        "--calibration",
        type=Path,
        nargs="+",
        default=None,
        help="slrig's calibration (folder, calibration.json or .yaml) or another tool's file (or files read "
        "together: intrinsics.yml extrinsics.yml); for a scan directory, instead of the one it was made with",
    )
    rec.add_argument(
        "--out",
        type=Path,
        default=None,
        help="scan directory to create; default: beside a scan directory, else <data_dir>/scans/<id>",
    )
    rec.add_argument("--config", type=Path, default=None, help="rig description for the scan settings (filters)")
    _calibration_options(rec)
    rec.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _calibration_options(p: argparse.ArgumentParser) -> None:
    """What a calibration file may not say (rig.calibrate.foreign.ForeignCalibrationOptions)."""
    p.add_argument("--camera", default=None, help="the camera's name (camera0)")
    p.add_argument("--projector", default=None, help="the projector's name (projector0)")
    p.add_argument(
        "--extrinsics",
        choices=["camera_to_projector", "projector_to_camera"],
        default=None,
        help="what the file's R, T map (camera_to_projector: as OpenCV's stereoCalibrate, camera first); "
        "default: as the file's format defines it",
    )
    p.add_argument("--world", choices=["camera", "projector"], default=None, help="the world frame's device (camera)")
    p.add_argument("--translation-scale", type=float, default=None, help="the file's length unit in mm (1)")
    p.add_argument("--camera-resolution", type=_size, default=None, help="WIDTHxHEIGHT where the file has none")
    p.add_argument("--projector-resolution", type=_size, default=None, help="WIDTHxHEIGHT where the file has none")
    p.add_argument(
        "--ignore-projector-distortion",
        action="store_true",
        default=None,
        help="leave out the projector's distortion (where the file's own reconstruction did)",
    )
    p.add_argument(
        "--calibration-fields",
        default=None,
        help="the file's names for fields slrig does not know it by, exact: camera_matrix=K,rotation=Rp,...",
    )


def _calibration_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    cal = sub.add_parser("calibration", help="show what slrig reads from a calibration file (any common format)")
    cal.add_argument("action", choices=["show"])
    cal.add_argument("files", type=Path, nargs="+", help="the file, or the files of one calibration read together")
    _calibration_options(cal)
    cal.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _store_command(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    store = sub.add_parser("store", help="the data directory offline: check its job records, move it")
    action = store.add_subparsers(dest="action", required=True)
    check = action.add_parser(
        "check",
        help="find job records the API cannot serve as stored; --repair moves them to the quarantine table",
        description="Exit 0: every record can be served (or --repair quarantined those that could not); "
        "1: damaged records remain; 2: no database, or a daemon holds the data directory (--repair).",
    )
    check.add_argument("--config", type=Path, default=None, help="rig description (YAML): its output.data_dir")
    check.add_argument("--data-dir", type=Path, default=None, help="the data directory (instead of --config's)")
    check.add_argument("--repair", action="store_true", help="quarantine damaged records (stop the daemon first)")
    check.add_argument("--json", action="store_true", help="print one JSON object")
    migrate = action.add_parser(
        "migrate",
        help="move a data directory whole (the shipped configs' old scans/ to slrig-data/, where scans are "
        "slrig-data/scans/<id>)",
        description="Renames OLD to NEW: refused while a daemon uses OLD, onto a NEW that exists, or across file "
        "systems. Then point output.data_dir at NEW.",
    )
    migrate.add_argument("old", type=Path, help="the data directory as it is (e.g. scans)")
    migrate.add_argument("new", type=Path, help="where it goes (e.g. slrig-data); must not exist")
    migrate.add_argument("--json", action="store_true", help="print one JSON object")


def parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="slrig", description="Structured-light 3D scanning rig.")
    parser.add_argument("--version", action="version", version=f"slrig {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    commands = (_scan_command, _live_command, _evaluate_command, _plan_command, _serve_command, _devices_command)
    more = (_doctor_command, _cal_command, _recognition_commands, _reconstruct_command, _calibration_command)
    for add in (*commands, *more, _store_command, batch_command):
        add(sub)
    return parser
