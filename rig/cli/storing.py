"""`slrig store check [--repair]`: the daemon's job records checked offline (rig.service.store_check);
`slrig store migrate OLD NEW`: a data directory moved whole (rig.service.migrate)."""

from __future__ import annotations

import argparse
import json

from rig.config import load_config
from rig.service import check_store, migrate_data_dir

EXIT_DAMAGED = 1


def cmd_store(args: argparse.Namespace) -> int:
    if args.action == "migrate":
        moved = migrate_data_dir(args.old, args.new)
        counts = {"scans": moved.scans, "calibrations": moved.calibrations}
        if args.json:
            print(json.dumps({"from": str(moved.source), "to": str(moved.target), **counts}))
        else:
            print(f"{moved.source} -> {moved.target}: {moved.scans} scans, {moved.calibrations} calibrations")
            print(f"  set output.data_dir: {moved.target} in your config")
        return 0
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
