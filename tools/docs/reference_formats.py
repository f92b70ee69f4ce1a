"""File formats' references: the pattern description, the manifest of a scan directory, and the
names another tool's calibration file may use."""

from __future__ import annotations

from schema_tables import cell, schema_sections

from rig.calibrate.device_files import DEVICE_FORMATS
from rig.calibrate.foreign import DISTORTION_LENGTHS, ForeignCalibrationOptions
from rig.calibrate.formats import FORMATS, GENERIC
from rig.patterns.spec import PatternSpec
from rig.store.manifest_fields import MANIFEST_FIELDS


def patterns_page() -> str:
    schema = PatternSpec.model_json_schema()
    lines = [
        "# Pattern description",
        "",
        "What a folder of frames showed, as `slrig reconstruct --patterns` and `slrig calibrate --patterns`",
        "read it (YAML), written from `rig.patterns.spec.PatternSpec` when this manual is built. A scan",
        "that keeps its frames writes one beside them (`patterns.yaml`).",
        "",
    ]
    return "\n".join(lines + schema_sections("PatternSpec", schema, schema.get("$defs", {}), level=2))


def manifest_page() -> str:
    lines = [
        "# Scan directory and manifest",
        "",
        "A scan directory (`slrig-data/scans/<id>/`, or `--out`) holds `manifest.json` beside its files.",
        "Its keys, from `rig.store.manifest_fields` (a test holds them to what `write_scan` writes):",
        "",
        "| key | what it holds |",
        "|---|---|",
    ]
    lines += [f"| `{key}` | {cell(text)} |" for key, text in MANIFEST_FIELDS.items()]
    return "\n".join(lines) + "\n"


def calibration_files_page() -> str:
    schema = ForeignCalibrationOptions.model_json_schema()
    lines = [
        "# Calibration files",
        "",
        "slrig writes its own calibration as `calibration.json` (with `calibration.yaml`, an OpenCV",
        "FileStorage copy, and the report), and reads either back. It also reads other tools'",
        "projector-camera calibrations (OpenCV FileStorage XML or YAML, plain YAML, JSON, MATLAB .mat),",
        "telling which tool wrote one by its fields, compared exactly, case and all (`rig.calibrate.formats.FORMATS`);",
        "several files are read as one calibration (`--calibration A B`), and `slrig calibration show",
        "FILE...` prints what it read. Each format's names:",
        "",
    ]
    for chosen in (*FORMATS, GENERIC):
        marks = ", ".join(f"`{m}`" for m in chosen.marks) or "none of the above"
        direction = chosen.extrinsics or "as the options say (camera_to_projector by default)"
        lines += [
            f"## {chosen.name}",
            "",
            f"Told by {marks}; from {chosen.source}. R, T: {direction}; lengths in {chosen.unit}.",
            "",
            "| field | names |",
            "|---|---|",
        ]
        lines += [
            f"| {field.replace('_', ' ')} | {', '.join(f'`{n}`' for n in names)} |"
            for field, names in chosen.names.items()
        ]
        lines.append("")
    lines += [
        "## Files of one device each",
        "",
        "Given two of them, the first file's device is the camera and the second's the projector;",
        "one alone is a camera (`slrig calibration show`). Their names are the fields' own.",
        "",
        "| format | defined by | fields | the pair's pose | lengths in |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| {name} | {source} | {' '.join(f'`{n}`' for n in names.split() if n not in ('or', 'a', 'folder', 'of'))} "
        f"| {pose} | {unit} |"
        for name, source, names, pose, unit in DEVICE_FORMATS
    ]
    lines.append("")
    lengths = ", ".join(str(n) for n in DISTORTION_LENGTHS)
    lines += [
        f"Distortion vectors hold {lengths} coefficients (OpenCV's order). What a file cannot say is",
        "given as options (`slrig reconstruct --camera-resolution ...`, `--calibration-fields`, or",
        "`calibration_options` over REST):",
        "",
    ]
    return "\n".join(lines + schema_sections("ForeignCalibrationOptions", schema, schema.get("$defs", {}), level=2))
