"""Adaptive projection in two passes at one exposure (rig.pipeline.mask_passes): the masks' steps
on either side of each edge of strong contrast, the passes merged by how far from a step each read
a pixel (rig.pipeline.pass_merge.merge_mask_passes)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rig.assembly import open_rig
from rig.cli import main
from rig.config import config_from_dict
from rig.evaluate.pairs import evaluate_on_bench
from rig.patterns import Correspondence
from rig.pipeline.hdr import scan_with_exposure
from rig.pipeline.mask_passes import step_band, two_pass_masks
from rig.pipeline.pass_merge import merge_mask_passes
from rig.pipeline.scan import make_codec
from tests.conftest import small_config_data, write_config

CHECKER = {"kind": "checker", "size_mm": 50.0, "colours": [[0.03] * 3, [1.0] * 3]}


def _corr(u: np.ndarray, quality: float) -> Correspondence:
    valid = np.isfinite(u)
    return Correspondence(valid, np.full(u.shape, quality, np.float32), np.zeros(u.shape, np.uint8), u=u)


def test_each_pixel_is_read_from_the_pass_farther_from_a_step_and_twice_where_both_are_far() -> None:
    truth = np.tile(np.arange(6, dtype=np.float64), (2, 1))
    first, second = truth + 0.1, truth - 0.1  # each pass's own noise
    first[:, 5] = np.nan  # clipped in the first pass
    lean_first = np.array([[0.0, 0.0, 0.2, 0.0, 0.0, 0.0]] * 2)  # the first pass's step beside column 2
    lean_second = np.array([[0.0, 0.3, 0.0, 0.01, 0.0, 0.0]] * 2)  # the second's beside column 1
    merged = merge_mask_passes([_corr(first, 0.2), _corr(second, 0.4)], [lean_first, lean_second])
    u = merged.u[0]
    assert u[1] == pytest.approx(first[0, 1])  # the first pass, whose step is far
    assert u[2] == pytest.approx(second[0, 2])  # the second
    # far from both steps (within the tie): both, weighted by quality squared (0.04 against 0.16)
    for column in (0, 3, 4):
        assert u[column] == pytest.approx((0.04 * first[0, column] + 0.16 * second[0, column]) / 0.2)
    assert u[5] == pytest.approx(second[0, 5])  # read by one pass only
    assert merged.valid.all() and merged.counts["mask_passes"] == 2
    # a pixel neither pass read stays unread
    neither = merge_mask_passes([_corr(np.full((1, 2), np.nan), 0.2)] * 2, [np.zeros((1, 2))] * 2)
    assert not neither.valid.any() and np.isnan(neither.u).all()


def test_the_second_pass_moves_each_step_to_the_other_side_of_the_edge() -> None:
    mask = np.ones((9, 12), np.float32)
    mask[:, 6:] = 0.3  # a highlight dimmed right of column 6, spread one pixel (margin 1) ...
    mask[:, 5] = 0.3  # ... onto the dark side
    spread, pulled_back = two_pass_masks([mask], margin_px=1)
    rows = slice(3, 6)  # away from the image's top and bottom
    assert (spread[0][rows, 4:] == np.float32(0.3)).all() and (spread[0][rows, :4] == 1).all()  # a pixel further
    assert (pulled_back[0][rows, :7] == 1).all() and (pulled_back[0][rows, 7:] == np.float32(0.3)).all()


def test_the_step_band_counts_only_the_lit_projector_pixels_beside_steps() -> None:
    light = np.ones((40, 60), np.float32)
    light[:, 30:] = 0.01
    rows, cols = np.indices((40, 60)).astype(np.float64)
    band = step_band(light, cols, rows, max_shift_px=0.25, blur_px=0.75)
    assert 2 / 60 <= band <= 6 / 60  # a few columns about the one step
    flat = step_band(np.full((40, 60), 0.2, np.float32), cols, rows, 0.25, 0.75)
    assert flat == 0.0
    unmapped = np.full((40, 60), np.nan)
    assert step_band(light, unmapped, unmapped, 0.25, 0.75) == 0.0


def _checker_box(passes: object) -> dict:
    data = small_config_data()
    data["simulation"]["scene"] = {"kind": "box"}
    data["simulation"]["texture"] = CHECKER
    data["scan"]["exposure"] = {
        "exposure": "auto",
        "adaptive_projection": True,
        "adaptive_passes": passes,
        "drop_outshone": True,
    }
    return data


def test_a_dark_and_white_object_takes_two_passes_and_they_read_the_edges_one_pass_loses() -> None:
    measured = {}
    for passes in (1, "auto"):
        with open_rig(config_from_dict(_checker_box(passes), f"passes {passes}")) as rig:
            result = scan_with_exposure(rig)
            measured[passes] = evaluate_on_bench(rig, result.pairs[0])
            per_scan = make_codec(rig, 0).frame_count
            record = result.exposure
    assert record is not None
    projection = record["adaptive_projection"]
    assert projection["passes"] == 2 and projection["step_band"]["projector0_camera0"] > 0.01  # auto chose two
    (chosen,) = {e for e in record["exposures_us"]["camera0"]}  # both passes at the one exposure
    assert record["exposures_us"]["camera0"] == [chosen, chosen]
    assert result.frames_projected == 3 * per_scan  # the pre-scan's and the two passes'
    assert len(projection["projector_blur_px"]["projector0_camera0"]) == 2
    # measured: 0.875 complete in one pass, 0.922 in two, rms 0.257 and 0.255 mm
    assert measured["auto"]["completeness"] > measured[1]["completeness"] + 0.03
    assert measured["auto"]["rms_mm"] <= measured[1]["rms_mm"]


def test_a_single_highlight_takes_one_pass() -> None:
    data = small_config_data()
    data["simulation"]["scene"] = {"kind": "sphere_on_plane"}
    data["simulation"]["material"] = {"specular": 0.5, "roughness": 0.15}
    data["scan"]["exposure"] = {"exposure": "auto", "adaptive_projection": True}
    with open_rig(config_from_dict(data, "sphere")) as rig:
        result = scan_with_exposure(rig)
    assert result.exposure is not None
    assert result.exposure["adaptive_projection"]["passes"] == 1
    assert len(result.exposure["exposures_us"]["camera0"]) == 1


def test_reprocessing_a_two_pass_scan_merges_its_passes_as_the_scan_did(tmp_path: Path) -> None:
    config = write_config(tmp_path, _checker_box(2))
    out = tmp_path / "scan"
    assert main(["scan", "--config", str(config), "--save-frames", "--out", str(out), "--json"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    with np.load(out / "adaptive_projection" / "projector0_camera0.npz") as kept:
        assert kept["light"].ndim == 3 and len(kept["light"]) == 2  # each pass's masks
    again = tmp_path / "again"
    assert main(["reconstruct", str(out), "--out", str(again), "--json"]) == 0
    redone = json.loads((again / "manifest.json").read_text())
    counts, recounted = manifest["pairs"][0]["counts"], redone["pairs"][0]["counts"]
    assert counts["mask_passes"] == recounted["mask_passes"] == 2
    assert recounted["points"] == counts["points"] and recounted["rejected_mask_edge"] == counts["rejected_mask_edge"]
