"""`slrig gallery add|list|remove` and `slrig identify`: recognition of stored scans."""

from __future__ import annotations

import argparse
import datetime as dt
import json
from pathlib import Path

from rig.config import load_config
from rig.errors import RecognitionError
from rig.recognition import UNKNOWN, Comparison, Gallery, Identification
from rig.service import (
    gallery_add,
    gallery_path,
    identify_scan,
    settings_from,
)


def _gallery_file(args: argparse.Namespace) -> Path:
    if args.gallery is not None:
        return args.gallery
    return gallery_path(load_config(args.config).output.data_dir)


def cmd_gallery(args: argparse.Namespace) -> int:
    path = _gallery_file(args)
    with Gallery(path) as gallery:
        if args.action == "add":
            options = {"rings": args.rings, "samples": args.samples, "inner_mm": args.inner_mm}
            options.update(outer_mm=args.outer_mm, distance=args.distance, spectrum=args.spectrum, frame=args.frame)
            entry = gallery_add(gallery, args.scan_dir, args.label, settings_from(options))
            _print(args.json, entry.as_dict(), f"added entry {entry.id}: {entry.label} (scan {entry.scan_id})")
        elif args.action == "list":
            entries = gallery.entries()
            if args.json:
                print(json.dumps({"gallery": str(path), "entries": [e.as_dict() for e in entries]}))
            else:
                print(f"{len(entries)} entries in {path}")
                for e in entries:
                    created = dt.datetime.fromtimestamp(e.created, dt.UTC).isoformat(timespec="seconds")
                    print(f"{e.id:>5}  {e.label:<24} scan {e.scan_id}  {created}")
        else:
            entry = gallery.remove(args.entry_id)
            _print(args.json, entry.as_dict(), f"removed entry {entry.id}: {entry.label} (scan {entry.scan_id})")
    return 0


def cmd_identify(args: argparse.Namespace) -> int:
    if args.top < 1:
        raise RecognitionError(f"--top: {args.top} is not a positive count")
    comparison: Comparison = "raw" if args.raw else "standardised"
    threshold = args.threshold
    if threshold is not None and not -1.0 <= threshold <= 1.0:
        raise RecognitionError(f"--threshold: {threshold:g} is not a score between -1 and 1")
    with Gallery(_gallery_file(args)) as gallery:
        scan_id, found = identify_scan(gallery, args.scan_dir, args.top, threshold, comparison)
    if args.json:
        print(json.dumps({"scan_id": scan_id, **found.as_dict()}))
        return 0
    print(f"scan {scan_id}: {verdict(found)}")
    digits = _digits([m.score for m in found.matches] + [found.threshold])
    for match in found.matches:
        print(f"  {match.score:+.{digits}f}  {match.label} (entry {match.entry_id}, scan {match.scan_id})")
    return 0


def verdict(found: Identification) -> str:
    """The label, and why: the best score beside the threshold it was held to."""
    best = found.matches[0]
    digits = _digits([best.score, found.threshold])
    score, threshold = f"{best.score:+.{digits}f}", f"{found.threshold:+.{digits}f}"
    held = f"the threshold {threshold} ({found.comparison} comparison; --threshold sets another)"
    if found.label == UNKNOWN:
        return f"unknown: the best match, {best.label}, scores {score}, below {held}"
    return f"{found.label}: scores {score}, at or above {held}"


def _digits(values: list[float]) -> int:
    """Decimals enough (3 to 8) that no two of `values` that differ print alike."""
    for digits in range(3, 9):
        printed = {f"{v:+.{digits}f}" for v in values}
        if len(printed) == len(set(values)):
            return digits
    return 8


def _print(as_json: bool, report: dict[str, object], text: str) -> None:
    print(json.dumps(report) if as_json else text)
