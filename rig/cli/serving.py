"""`slrig serve`: the daemon (the only command that loads the web stack)."""

from __future__ import annotations

import argparse
import logging
import sys

from rig.assembly.memory import check_memory
from rig.config import load_config
from rig.daemon.server import load_api_key, serve
from rig.errors import ConfigError


def cmd_serve(args: argparse.Namespace) -> int:
    if not 0 <= args.port <= 65535:
        raise ConfigError("--port", [f"--port: {args.port} is outside 0..65535"])
    config = load_config(args.config)
    check_memory(config)  # at start, not at the first job
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    key = load_api_key(args.api_key_file, config.output.data_dir)
    return serve(config, args.host, args.port, key)
