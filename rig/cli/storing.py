"""`slrig store check [--repair]`: the daemon's job records checked offline (rig.service.store_check)."""

from __future__ import annotations

import argparse
import json

from rig.config import load_config
from rig.service.store_check import check_store

EXIT_DAMAGED = 1


def cmd_store(args: argparse.Namespace) -> int:
    data_dir = args.data_dir if args.data_dir is not None else load_config(args.config).output.data_dir
    report = check_store(data_dir, repair=args.repair)
    if args.json:
        print(json.dumps(report.as_dict()))
    else:
        print(f"{report.database}: {report.records} records, integrity {report.integrity}")
        for found in report.damaged:
            print(f"  damaged {found['id']}: {found['problem']}")
        if report.quarantined:
            print(f"  {report.quarantined} moved to the quarantine table (its folder, if any, is left in place)")
        elif report.damaged:
            print("  run again with --repair (the daemon stopped) to quarantine them")
    return 0 if report.clean else EXIT_DAMAGED
