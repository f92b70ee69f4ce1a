"""The `slrig` command line.

Exit codes: 0 success; 1 the scan failed (device fault); 2 bad input (config, options, files).
Each command's module is imported when it runs, so `slrig serve` loads neither the calibration
nor the simulator it does not use.
"""

from __future__ import annotations

import importlib
import sys

from drivers.errors import DeviceError
from rig.cli.arguments import parser
from rig.errors import ScanError, SlrigError

EXIT_FAILED = 1
EXIT_BAD_INPUT = 2

# command -> (module, function); the module is imported only for its own command
COMMANDS = {
    "scan": ("rig.cli.scanning", "cmd_scan"),
    "eval": ("rig.cli.scanning", "cmd_eval"),
    "live": ("rig.cli.live", "cmd_live"),
    "calibrate": ("rig.cli.bench_setup", "cmd_calibrate"),
    "devices": ("rig.cli.bench_setup", "cmd_devices"),
    "doctor": ("rig.cli.bench_setup", "cmd_doctor"),
    "serve": ("rig.cli.serving", "cmd_serve"),
    "plan": ("rig.cli.planning", "cmd_plan"),
    "gallery": ("rig.cli.recognising", "cmd_gallery"),
    "identify": ("rig.cli.recognising", "cmd_identify"),
    "reconstruct": ("rig.cli.reconstructing", "cmd_reconstruct"),
    "calibration": ("rig.cli.calibration_files", "cmd_calibration"),
    "store": ("rig.cli.storing", "cmd_store"),
    "batch": ("rig.cli.batching", "cmd_batch"),
}


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    module, function = COMMANDS[args.command]
    try:
        handler = getattr(importlib.import_module(module), function)
        return int(handler(args))
    except ScanError as exc:
        print(f"slrig: scan failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except DeviceError as exc:
        print(f"slrig: device error: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except SlrigError as exc:
        print(f"slrig: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("slrig: interrupted", file=sys.stderr)
        return 130
