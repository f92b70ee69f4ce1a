"""Exposure from what the camera sees (rig.pipeline.exposure) and HDR by bracketing
(rig.pipeline.hdr): auto-exposure from the histogram, brackets that reach the darkest and the
brightest, a high-contrast object scanned whole, and a camera without the control refused."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from drivers.errors import DeviceStateError
from rig.assembly import open_rig
from rig.cli import main
from rig.config import config_from_dict
from rig.evaluate.pairs import evaluate_on_bench
from rig.pipeline.exposure import STEP, ExposureSettings, Look, auto_exposure, bracket
from rig.pipeline.hdr import scan_with_exposure
from tests.conftest import small_config_data, write_config

SETTINGS = ExposureSettings()


def _look(white: np.ndarray, exposure_us: float = 1000.0) -> Look:
    return Look(exposure_us, white.astype(np.uint8), np.full(white.shape, 2, np.uint8), 255)


def test_auto_exposure_follows_the_histogram_not_a_rule() -> None:
    dim = _look(np.full((40, 40), 50.0))
    exposure, settled = auto_exposure(dim, SETTINGS)
    assert settled and exposure == pytest.approx(1000.0 * 0.85 * 255 / 50, rel=0.03)  # the longest that reads all
    spotted = np.full((40, 40), 50.0)
    spotted[:3, :3] = 250  # a highlight on 0.6 % of the pixels: it clips, the rest is read
    assert auto_exposure(_look(spotted), SETTINGS)[0] == pytest.approx(exposure, rel=0.03)
    dark_half = np.full((40, 40), 200.0)
    dark_half[:, :20] = 20.0  # half dark, half bright: no exposure reads both, the one that reads one half
    chosen = auto_exposure(_look(dark_half), SETTINGS)[0] / 1000.0
    assert chosen == pytest.approx(0.85 * 255 / 20, rel=0.03)  # ties: the longer, the less noise
    clipped = np.full((40, 40), 255.0)
    exposure, settled = auto_exposure(_look(clipped), SETTINGS)
    assert not settled and exposure < 1000.0  # what lies above full scale is unknown: look again, shorter


def test_a_bracket_reaches_the_darkest_lit_pixels_and_the_brightest() -> None:
    white = np.full((50, 50), 200.0)
    white[:, :25] = 6.0  # black rubber beside white paper: 4 counts of contrast over the black frame
    exposures = bracket(_look(white), SETTINGS)
    assert exposures[0] == pytest.approx(1000.0 * 0.85 * 255 / 200)  # the brightest just under full scale
    assert all(b == pytest.approx(STEP * a) for a, b in itertools.pairwise(exposures))
    # the longest shows the dark half with the contrast the decoders need
    assert exposures[-1] * 4.0 / 1000.0 >= SETTINGS.min_contrast * 255
    assert len(bracket(_look(np.full((50, 50), 200.0)), SETTINGS)) == 1  # nothing dark: one exposure


def _checker_config(hdr: object, codec: str) -> dict:
    data = small_config_data()
    data["scan"]["codec"] = codec
    data["simulation"]["texture"] = {"kind": "checker", "size_mm": 25.0, "colours": [[0.03] * 3, [1.0] * 3]}
    data["scan"]["exposure"] = {"exposure": "auto", "hdr": hdr}
    return data


@pytest.mark.parametrize("codec", ["gray", "phase"])
def test_hdr_scans_a_dark_and_white_object_as_whole_as_a_grey_one(codec: str) -> None:
    completeness = {}
    grey = _checker_config(None, codec)
    del grey["simulation"]["texture"]
    for name, data in (
        ("grey", grey),
        ("single", _checker_config(None, codec)),
        ("hdr", _checker_config("auto", codec)),
    ):
        with open_rig(config_from_dict(data, "hdr")) as rig:
            result = scan_with_exposure(rig)
            completeness[name] = evaluate_on_bench(rig, result.pairs[0])["completeness"]
            assert result.exposure is not None and result.exposure["mode"] == ("hdr" if name == "hdr" else "auto")
    assert completeness["single"] < 0.7 * completeness["grey"]  # one exposure: the dark squares read no pattern
    assert completeness["hdr"] > 0.9 * completeness["grey"]


@pytest.mark.parametrize(
    ("asked", "named"),
    [
        ({"hdr": [1000.0, 4000.0]}, "HDR"),
        ({"exposure": "auto"}, "auto-exposure"),
        ({"adaptive_projection": True}, "adaptive projection"),
    ],
)
def test_a_camera_without_exposure_control_refuses_naming_it(asked: dict, named: str) -> None:
    data = _checker_config(None, "gray")
    data["scan"]["exposure"] = {"exposure": "camera", **asked}
    with open_rig(config_from_dict(data, "refused")) as rig:
        rig.cameras[0].has_exposure = False  # as a driver without the control says
        with pytest.raises(DeviceStateError, match=f"{named} needs the camera's exposure control"):
            scan_with_exposure(rig)
        assert all(p.is_dark for p in rig.projectors)


def test_the_command_line_takes_exposure_and_hdr(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = write_config(tmp_path, _checker_config(None, "gray"))
    out = tmp_path / "scan"
    assert main(["scan", "--config", str(config), "--hdr", "3", "--out", str(out), "--json"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["exposure"]["mode"] == "hdr" and len(manifest["exposure"]["exposures_us"]["camera0"]) == 3
    assert manifest["pairs"][0]["counts"]["hdr_exposures"] == 3
    capsys.readouterr()
    assert main(["scan", "--config", str(config), "--exposure", "fast", "--out", str(tmp_path / "x")]) != 0
    assert "--exposure: 'fast'" in capsys.readouterr().err


def test_auto_exposure_and_hdr_stay_within_the_cameras_range_and_a_given_exposure_outside_is_named() -> None:
    from rig.errors import ConfigError

    with open_rig(config_from_dict(_checker_config("auto", "gray"), "hdr")) as rig:
        camera = rig.cameras[0]
        camera.exposure_range_us = (50.0, 12_000.0)  # as a driver that cannot expose longer says
        result = scan_with_exposure(rig)
        assert result.exposure is not None
        taken = result.exposure["exposures_us"][camera.name]
        assert max(taken) == 12_000.0 and min(taken) >= 50.0  # the dark squares asked for longer
        looked = [look["exposure_us"] for look in result.exposure["looks"][camera.name]]
        assert all(50.0 <= e <= 12_000.0 for e in looked)
    data = _checker_config(None, "gray")
    data["scan"]["exposure"]["exposure"] = 20_000.0
    with open_rig(config_from_dict(data, "fixed")) as rig:
        rig.cameras[0].exposure_range_us = (50.0, 12_000.0)
        with pytest.raises(ConfigError, match=r"scan\.exposure\.exposure: 20000 us is outside camera0's exposures"):
            scan_with_exposure(rig)


def test_an_hdr_scans_frames_are_kept_and_reprocessed_as_the_scan_merged_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = write_config(tmp_path, _checker_config(None, "gray"))
    out = tmp_path / "scan"
    assert main(["scan", "--config", str(config), "--hdr", "2", "--save-frames", "--out", str(out), "--json"]) == 0
    scanned = json.loads(capsys.readouterr().out)
    manifest = json.loads((out / "manifest.json").read_text())
    per_pass = manifest["economy"]["frames_projected"] // 2
    assert len(manifest["files"]["frames"]["projector0_camera0"]) == 2 * per_pass  # both passes, one after another
    again = tmp_path / "again"
    assert main(["reconstruct", str(out), "--out", str(again), "--json"]) == 0
    redone = json.loads(capsys.readouterr().out)
    assert redone["points"] == scanned["points"] and redone["frames"] == scanned["frames"]
    reprocessed = json.loads((again / "manifest.json").read_text())
    assert reprocessed["pairs"][0]["counts"]["hdr_exposures"] == 2
    assert reprocessed["exposure"]["exposures_us"] == manifest["exposure"]["exposures_us"]


def test_a_planned_ring_scan_takes_hdr_and_reads_the_dark_paint(tmp_path: Path) -> None:
    radii = [float(r) for r in range(12, 120, 6)]
    plan = tmp_path / "plan.json"
    ring_plan = {"format": "slrig-ring-plan/1", "tolerance_mm": 0.2, "center_px": [128.0, 96.0], "radii_px": radii}
    plan.write_text(json.dumps(ring_plan))
    config = write_config(tmp_path, _checker_config(None, "phase"))
    manifests = {}
    for name, asked in (("auto", ["--exposure", "auto"]), ("hdr", ["--exposure", "auto", "--hdr", "auto"])):
        out = tmp_path / name
        assert main(["scan", "--config", str(config), "--plan", str(plan), *asked, "--out", str(out), "--json"]) == 0
        manifests[name] = json.loads((out / "manifest.json").read_text())
    hdr, auto = manifests["hdr"], manifests["auto"]
    assert hdr["codec"]["name"] == "rings" and hdr["exposure"]["mode"] == "hdr"
    passes = len(hdr["exposure"]["exposures_us"]["camera0"])
    assert passes >= 2 and hdr["pairs"][0]["counts"]["hdr_exposures"] == passes
    assert hdr["economy"]["frames_projected"] == passes * auto["economy"]["frames_projected"]
    # the dark squares' rings read too (measured: 5,529 ring points against 2,970 at one exposure)
    assert hdr["pairs"][0]["counts"]["points"] > 1.5 * auto["pairs"][0]["counts"]["points"]
