"""`slrig serve`: the daemon (the only command that loads the web stack)."""

from __future__ import annotations

import argparse
import logging
import sys

from rig.assembly import check_memory
from rig.config import load_config
from rig.daemon import install_redaction, load_api_keys, serve
from rig.errors import ConfigError


def cmd_serve(args: argparse.Namespace) -> int:
    if not 0 <= args.port <= 65535:
        raise ConfigError("--port", [f"--port: {args.port} is outside 0..65535"])
    config = load_config(args.config)
    check_memory(config)  # at start, not at the first job
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    keys = load_api_keys(args.api_key_file, args.read_key_file, config.output.data_dir)
    install_redaction(keys.values())  # no key in any log line, the access log's included
    return serve(config, args.host, args.port, keys.admin, keys.read)
