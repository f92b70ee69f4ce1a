"""Adaptive projection (rig.pipeline.projection_mask): patterns dimmed per projector pixel where the
camera would clip, from a pre-scan; one exposure then reads a glossy highlight and the dark
surface beside it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from rig.assembly import open_rig
from rig.cli import main
from rig.config import config_from_dict
from rig.evaluate.pairs import evaluate_on_bench
from rig.patterns import Correspondence
from rig.pipeline.exposure import ExposureSettings, Look
from rig.pipeline.hdr import scan_with_exposure
from rig.pipeline.mask_skew import MaskSkew, lean
from rig.pipeline.projection_mask import MaskSettings, light_share, scattered_mask
from rig.pipeline.scan import make_codec
from tests.conftest import small_config_data, write_config

GLOSS = {"specular": 0.8, "roughness": 0.08}


def _identity_map(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    rows, cols = np.indices((height, width)).astype(np.float64)
    return cols, rows


def test_each_projector_pixel_takes_the_least_share_of_the_camera_pixels_it_lights() -> None:
    u, v = _identity_map(60, 80)
    share = np.ones((60, 80))
    share[20:30, 30:40] = 0.1
    share[25, 35] = 0.05  # one camera pixel asks for less than the rest
    mask = scattered_mask((80, 60), u, v, share, MaskSettings(margin_px=2, smooth_px=0.0))
    assert mask[25, 35] == pytest.approx(0.05)
    assert mask[20:30, 30:40].max() <= 0.1 + 1e-6  # never brighter than a pixel asks
    assert (mask[18:20, 30:40] < 1.0).all() and mask[17, 35] == 1.0  # spread by the margin, no further
    assert (mask[:10] == 1.0).all()  # nothing asked, nothing dimmed
    # a camera pixel lighting no projector pixel, or mapped nowhere, dims nothing
    u[share < 1] = np.nan
    assert (scattered_mask((80, 60), u, v, share, MaskSettings()) == 1.0).all()


def test_the_share_of_light_a_pixel_takes_follows_its_white_scaled_to_the_exposure() -> None:
    settings = ExposureSettings()
    white = np.array([[100, 200, 255, 10]], np.uint16)
    black = np.array([[0, 50, 0, 10]], np.uint16)
    share = light_share(Look(1000.0, white, black, 255), 2000.0, settings)
    target = settings.target * 255
    assert share[0, 0] == pytest.approx(min(1.0, target / 200))  # twice the exposure: 200 counts
    assert share[0, 1] == pytest.approx((target - 100) / 300)  # its dark part (ambient) is not the projector's
    assert share[0, 2] == pytest.approx(target / 510)  # clipped at the short look: at least full scale
    assert share[0, 3] == 1.0  # no light of the projector's: nothing to dim


def _step(width: int = 60, height: int = 40, at: int = 30, dim: float = 0.1) -> np.ndarray:
    light = np.ones((height, width), np.float32)
    light[:, at:] = dim
    return light


def test_the_light_leans_toward_the_bright_side_of_a_step_and_only_near_it() -> None:
    light = _step()
    shift = lean(light, 0.7, axis=1)
    assert shift[20, 30] < -0.3  # the dim side's first pixel: mostly its bright neighbour's light
    assert -0.3 < shift[20, 29] < 0.0  # the bright side's last: a little pulled back from the dim side
    assert np.abs(shift[:, :26]).max() < 1e-3 and np.abs(shift[:, 34:]).max() < 1e-3
    assert np.abs(lean(light, 0.7, axis=0)).max() < 1e-3  # along the step: nothing leans
    assert np.abs(lean(np.full((40, 60), 0.2, np.float32), 0.7, axis=1)).max() < 1e-3  # any even light


def _leaning_decode(light: np.ndarray, blur: float) -> tuple[Correspondence, np.ndarray]:
    """A decode whose columns lean as `light` under a projector `blur` would make them, and the truth."""
    true_u, v = _identity_map(*light.shape)
    true_u = true_u + 0.3  # camera pixels between projector pixels
    decoded = true_u.copy()
    for _ in range(20):  # the pixel reads its true column plus the lean there
        decoded = true_u + ndimage.map_coordinates(lean(light, blur, 1), [v, true_u], order=1)
    valid = np.ones(light.shape, bool)
    corr = Correspondence(valid, np.ones(light.shape, np.float32), np.zeros(light.shape, np.uint8), u=decoded)
    return corr, true_u


def test_the_masks_lean_is_measured_on_the_scan_and_taken_off_its_decode() -> None:
    light = _step()
    corr, true_u = _leaning_decode(light, 0.6)
    v = _identity_map(*light.shape)[1]
    skew = MaskSkew(light, true_u, v, np.ones(light.shape, bool), max_shift_px=0.25, fallback_blur_px=1.2)
    unleaned = skew.applied(corr)
    fixed, blur = unleaned.corr, unleaned.blur_px
    assert blur == pytest.approx(0.6, abs=0.051)  # the blur the decode leaned by, not the fallback
    kept = fixed.valid
    assert np.abs(fixed.u[kept] - true_u[kept]).max() < 0.005  # where the decode was 0.05 px off
    assert np.abs(corr.u[kept] - true_u[kept]).max() > 0.05
    assert not kept[:, 29:31].any() and kept[:, :29].all() and kept[:, 31:].all()  # a third of a pixel and more
    assert fixed.counts["rejected_mask_edge"] == int((~kept).sum())
    # too few pixels near a step to tell: the fallback blur, and nothing measured
    flat = np.ones_like(light)
    assert MaskSkew(flat, true_u, v, np.ones(light.shape, bool), 0.25, 0.75).applied(corr).blur_px is None


def test_sparse_samples_lose_the_pixels_beside_a_step_of_the_mask() -> None:
    light = _step()
    u, v = _identity_map(*light.shape)
    corr = Correspondence(np.ones(light.shape, bool), np.ones(light.shape, np.float32), np.zeros(light.shape, np.uint8))
    unleaned = MaskSkew(light, u, v, np.ones(light.shape, bool), 0.25, 0.75).applied(corr)
    fixed, blur = unleaned.corr, unleaned.blur_px
    assert blur is None
    left_out = ~fixed.valid.all(axis=0)
    assert left_out[30] and not left_out[:28].any() and not left_out[32:].any()


def _glossy(adaptive: bool, exposure: object = "auto", passes: object = 1) -> dict:
    data = small_config_data()
    data["simulation"]["material"] = GLOSS
    data["simulation"]["scene"] = {"kind": "steps"}
    data["scan"]["exposure"] = {"exposure": exposure, "adaptive_projection": adaptive, "adaptive_passes": passes}
    return data


def test_adaptive_projection_reads_a_machined_part_whole_in_one_exposure() -> None:
    with open_rig(config_from_dict(_glossy(True), "adaptive")) as rig:
        result = scan_with_exposure(rig)
        adaptive = evaluate_on_bench(rig, result.pairs[0])
        chosen = rig.cameras[0].exposure_us
        per_scan = make_codec(rig, 0).frame_count
    record = result.exposure
    assert record is not None and record["mode"] == "adaptive projection"
    projection = record["adaptive_projection"]
    assert 1.8 < projection["response_exponent"] < 2.6  # the simulated projector's gamma is 2.2
    assert projection["masks"][0]["least"] < 0.5  # the highlights were dimmed ...
    assert result.exposure["exposures_us"]["camera0"] == [chosen]  # ... in one exposure
    assert result.frames_projected == 2 * per_scan  # the pre-scan's and the scan's
    with open_rig(config_from_dict(_glossy(False, chosen), "unmasked")) as rig:  # the same exposure, no masks
        plain = scan_with_exposure(rig)
        unmasked = evaluate_on_bench(rig, plain.pairs[0])
    assert plain.pairs[0].counts["rejected_saturated"] > 20 * max(1, result.pairs[0].counts["rejected_saturated"])
    # more of the part (measured: 0.98 against 0.87 of it), the highlights read as well as the rest
    # (rms 0.228 against 0.240 mm): the masks' lean taken off, with the blur it was measured at
    assert adaptive["completeness"] > 0.95 and adaptive["completeness"] > unmasked["completeness"] + 0.05
    assert adaptive["rms_mm"] < unmasked["rms_mm"]
    (blur,) = projection["projector_blur_px"]["projector0_camera0"]
    assert 0.5 <= blur <= 1.0  # the simulated lens's 0.5 px, with the sampling between pixels


def test_the_command_line_takes_adaptive_projection(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = write_config(tmp_path, _glossy(False))
    out = tmp_path / "scan"
    assert main(["scan", "--config", str(config), "--adaptive-projection", "--out", str(out), "--json"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["exposure"]["mode"] == "adaptive projection"
    assert manifest["exposure"]["adaptive_projection"]["masks"][0]["dimmed_share"] > 0


def test_reprocessing_an_adaptive_scans_frames_takes_the_masks_lean_off_as_the_scan_did(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = write_config(tmp_path, _glossy(False))
    out = tmp_path / "scan"
    assert main(["scan", "--config", str(config), "--adaptive-projection", "--save-frames", "--out", str(out)]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert set(manifest["files"]["adaptive_projection"]) == {"projector0_camera0"}
    again = tmp_path / "again"
    assert main(["reconstruct", str(out), "--out", str(again), "--json"]) == 0
    redone = json.loads((again / "manifest.json").read_text())
    counts, recounted = manifest["pairs"][0]["counts"], redone["pairs"][0]["counts"]
    assert recounted["rejected_mask_edge"] == counts["rejected_mask_edge"] > 0  # the same pixels left out
    assert recounted["points"] == counts["points"]
    assert redone["exposure"]["adaptive_projection"] == manifest["exposure"]["adaptive_projection"]
    # a kept mask gone missing is refused, naming it, rather than reprocessed without its correction
    (out / "adaptive_projection" / "projector0_camera0.npz").unlink()
    capsys.readouterr()
    assert main(["reconstruct", str(out), "--out", str(tmp_path / "third"), "--json"]) != 0
    assert "adaptive_projection/projector0_camera0.npz" in capsys.readouterr().err
    assert not (tmp_path / "third").exists()
