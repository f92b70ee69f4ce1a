"""What the commands share: loading the config with the command line's overrides, progress."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rig.cli.arguments import MESH_FIT_SIZE_MM
from rig.config import SCENE_SHAPES, RigConfig, load_config
from rig.errors import ConfigError
from rig.patterns import codec_class
from rig.progress import ProgressCallback, StageLines, TerminalBar


def load(args: argparse.Namespace) -> RigConfig:
    if args.codec:
        codec_class(args.codec)  # an unknown name fails here, naming the known ones
    config = load_config(args.config)
    if args.codec:
        config = config.with_codec(args.codec)
    exposure, hdr = getattr(args, "exposure", None), getattr(args, "hdr", None)
    adaptive_projection = getattr(args, "adaptive_projection", False)
    if exposure is not None or hdr is not None or adaptive_projection:
        config = config.with_exposure(exposure, hdr, adaptive_projection)
    return config


def scene_override(config: RigConfig, scene: str) -> RigConfig:
    if scene in SCENE_SHAPES and scene != "mesh":
        return config.with_scene({"kind": scene})
    path = Path(scene)
    if path.is_file():
        return config.with_scene({"kind": "mesh", "path": str(path.resolve()), "fit_size_mm": MESH_FIT_SIZE_MM})
    names = ", ".join(k for k in SCENE_SHAPES if k != "mesh")
    raise ConfigError("--scene", [f"--scene: {scene!r} is neither a scene name ({names}) nor a mesh file"])


def progress_bar(args: argparse.Namespace) -> ProgressCallback | None:
    """On stderr: a bar on a terminal, a line per stage elsewhere, nothing with --json (whose stdout
    is the one JSON object)."""
    if getattr(args, "json", False):
        return None
    return TerminalBar() if sys.stderr.isatty() else StageLines()
