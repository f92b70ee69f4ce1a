"""Calibration from other systems' captures (`slrig calibrate --images DIR --patterns spec.yaml`),
and the lens models for few views."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from rig.calibrate.boards import Board
from rig.calibrate.described import board_image
from rig.calibrate.foreign import ForeignCalibrationOptions, read_foreign_calibration
from rig.calibrate.models import LensModel, choose, fit
from rig.cli import main
from rig.config.calibration import BoardConfig
from rig.patterns.spec import PatternSpec
from rig.store.frames import read_frames
from tests.conftest import shared_data

PROCAM = {
    "projector": {"resolution": [2048, 1536], "code_step_px": 2},
    "frames": {"files": "graycode_*.png"},
    "gray": {"axes": ["columns", "rows"], "white_black": "last"},
}


@pytest.fixture(scope="module")
def procam(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    sample = shared_data("procam-calibration", "sample_data")
    folder = tmp_path_factory.mktemp("procam")
    description = folder / "procam.yaml"
    description.write_text(yaml.safe_dump(PROCAM))
    out = folder / "calibration"
    args = ["calibrate", "rig", "--images", str(sample), "--patterns", str(description), "--view-glob", "capture_*"]
    assert main([*args, "--board", "checker:10x8:75", "--out", str(out), "--json"]) == 0
    document = json.loads((out / "calibration.json").read_text())
    options = ForeignCalibrationOptions(projector_resolution=(2048, 1536))
    authors = read_foreign_calibration(sample / "calibration_result.xml", options)
    return {"document": document, "authors": authors, "sample": sample, "out": out}


def test_real_captures_calibrate_close_to_the_authors_camera_and_measure_the_board_better(
    procam: dict[str, object],
) -> None:
    document, authors = procam["document"], procam["authors"]
    assert isinstance(document, dict)
    camera, projector = (np.array(d["K"]) for d in document["devices"])
    truth = authors.camera.K  # type: ignore[attr-defined]
    # the camera, well determined by five views, agrees with the authors' to 0.3 %
    assert abs(camera[0, 0] / truth[0, 0] - 1) < 0.003 and abs(camera[1, 1] / truth[1, 1] - 1) < 0.003
    assert np.hypot(*(camera[:2, 2] - truth[:2, 2])) < 40  # the centre, within its 3 std
    report = document["report"]
    assert report["devices"]["camera0"]["std"]["fx"] < 0.01 * camera[0, 0]
    # the projector is where the two differ: the board as a ruler says which measures true
    ruler = report["board_check"]["camera0+projector0"]
    assert abs(ruler["square_error_pct"]) < 0.1 and abs(ruler["worst_view_square_error_pct"]) < 0.5
    assert ruler["plane_rms"] < 1.0
    assert projector[1, 2] > 1536  # a projector's lens shift: its centre below the image
    assert any("two even counts" in w for w in report["warnings"])


def test_the_board_found_in_the_frames_mean_when_there_is_no_white_frame(procam: dict[str, object]) -> None:
    spec = PatternSpec.model_validate(PROCAM)
    coded_only = PatternSpec.model_validate({**PROCAM, "gray": {"axes": ["columns", "rows"], "white_black": "none"}})
    sample = procam["sample"]
    assert isinstance(sample, Path)
    frames = read_frames(sample / "capture_0", spec.frames, len(spec.roles()))
    board = Board(BoardConfig(squares=(10, 8), square_mm=75))
    white = board.detect(board_image(frames.frames, spec, "white"))
    for source in ("auto", "mean", "modulation"):
        found = board.detect(board_image(frames.frames[:-2], coded_only, source))  # type: ignore[arg-type]
        assert len(found) == len(white) == 63
        assert np.abs(found.points - white.points).max() < 1.0, source


def test_bad_inputs_are_refused_naming_the_field_and_nothing_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    description = tmp_path / "spec.yaml"
    description.write_text(yaml.safe_dump(PROCAM))
    images = tmp_path / "captures"
    (images / "capture_0").mkdir(parents=True)
    cv2.imwrite(str(images / "capture_0" / "graycode_00.png"), np.zeros((8, 8), np.uint8))
    out = tmp_path / "out"
    base = ["calibrate", "rig", "--images", str(images), "--patterns", str(description), "--out", str(out)]
    refusals = {
        (): "the pattern description has 42 frames (columns: 20 Gray; rows: 20 Gray; white and black 2), 1 files match",
        ("--board", "checker:10x8"): "--board: 'checker:10x8' is not KIND:COLSxROWS:SQUARE_MM",
        ("--board", "charuco:10x8:30:40"): "--board: marker_mm 40 must be smaller than square_mm 30",
        ("--board", "charuco:10x8:30:20:DICT_9X9"): "--board dictionary",
        ("--board", "checker:10x2:75"): "--board: squares [10, 2]: a board needs 3 to 100",
        ("--model", "k1+fixed_everything"): "--model: model 'k1+fixed_everything'",
        ("--view-glob", "pose_*"): "has no sub-folders matching 'pose_*'",
    }
    for extra, message in refusals.items():
        assert main([*base, *extra]) == 2
        assert message in capsys.readouterr().err, extra
    one_axis = tmp_path / "columns.yaml"
    one_axis.write_text(yaml.safe_dump({**PROCAM, "gray": {"axes": ["columns"], "white_black": "last"}}))
    assert main([*base[:5], str(one_axis), *base[6:]]) == 2
    assert "needs columns and rows (gray.axes or phase.axes)" in capsys.readouterr().err
    assert not out.exists()


def _synthetic_views(
    K: np.ndarray, dist: np.ndarray, size: tuple[int, int], count: int, noise_px: float
) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """A 9x6-corner board of 20 mm squares seen `count` times at 400-600 mm, tilted up to 30 deg."""
    rng = np.random.default_rng(7)
    grid = np.zeros((54, 3))
    grid[:, :2] = np.mgrid[0:9, 0:6].T.reshape(-1, 2) * 20.0 - [80, 50]
    objects, images = {}, {}
    for v in range(count):
        rvec = rng.uniform(-0.5, 0.5, 3) * [1, 1, 0.3]
        tvec = np.array([rng.uniform(-60, 60), rng.uniform(-40, 40), rng.uniform(400, 600)])
        points, _ = cv2.projectPoints(grid, rvec, tvec, K, dist)
        objects[v] = grid
        images[v] = points.reshape(-1, 2) + rng.normal(0, noise_px, (54, 2))
    return objects, images


def test_auto_keeps_the_distortion_the_views_determine_and_drops_the_rest() -> None:
    size = (1280, 1024)
    K = np.array([[1800.0, 0, 650], [0, 1800, 500], [0, 0, 1]])
    barrel = np.array([-0.25, 0.15, 0, 0, 0])
    lens = choose(None, *_synthetic_views(K, barrel, size, 12, 0.1), size)
    assert lens.model.distortion == "k1k2"  # k1 and k2 are there, the tangential terms and k3 are not
    assert abs(lens.K[0, 0] - 1800) < 3 * lens.std["fx"]
    plain = choose(None, *_synthetic_views(K, np.array([-0.2, 0, 0, 0, 0]), size, 12, 0.1), size)
    assert plain.model.distortion == "k1"
    assert set(plain.held_out_px) == {"k1", "k1k2_tangential"}


def test_constraints_fix_what_they_name() -> None:
    size = (1280, 1024)
    K = np.array([[1800.0, 0, 700], [0, 1790, 450], [0, 0, 1]])
    objects, images = _synthetic_views(K, np.zeros(5), size, 6, 0.2)
    fixed = fit(LensModel.parse("k1+fixed_centre+fixed_aspect"), objects, images, size)  # type: ignore[arg-type]
    assert fixed.K[0, 2] == pytest.approx(639.5) and fixed.K[1, 2] == pytest.approx(511.5)
    assert fixed.K[0, 0] == pytest.approx(fixed.K[1, 1])
    assert set(fixed.std) == {"fy", "k1"}  # the free parameters, each with its deviation
    free = fit(LensModel("k1"), objects, images, size)
    assert abs(free.K[0, 2] - 700) < 3 * free.std["cx"] and abs(free.K[1, 1] - 1790) < 3 * free.std["fy"]


def test_the_report_names_every_view_it_dropped_and_its_folder() -> None:
    """A capture folder whose board was not found is named in the report, not dropped unseen."""
    from rig.calibrate.boards import Board, Detection
    from rig.calibrate.report import report
    from rig.calibrate.solve import calibrate_cameras
    from rig.calibrate.views import View
    from rig.config.calibration import BoardConfig

    board = Board(BoardConfig(squares=(10, 7), square_mm=20.0))
    ids = np.arange(board.corner_count)
    grid = board.object_points(ids)
    K = np.array([[1800.0, 0, 640], [0, 1800, 512], [0, 0, 1]])
    rng = np.random.default_rng(3)
    views = []
    for v in range(8):
        rvec = rng.uniform(-0.4, 0.4, 3) * [1, 1, 0.3]
        tvec = np.array([rng.uniform(-40, 40), rng.uniform(-30, 30), rng.uniform(500, 700)])
        points, _ = cv2.projectPoints(grid, rvec, tvec, K, np.zeros(5))
        views.append(View(v, {0: Detection(ids, points.reshape(-1, 2))}, label=f"capture_{v}"))
    views.append(View(8, label="capture_8"))  # the board was not found in this folder's frames
    device = calibrate_cameras(views, board, ["camera0"], [(1280, 1024)], "k1")[0]
    assert device.rejected[8] == "board not found (capture_8)"
    named = report([device])["devices"]["camera0"]
    assert named["rejected_views"]["8"] == "board not found (capture_8)" and 8 not in named["views_used"]
    assert len(named["views_used"]) == 8


@pytest.mark.parametrize(("fy", "warned"), [(1800.0, False), (2880.0, True)])
def test_a_device_whose_pixels_come_out_far_from_square_is_warned_of(fy: float, warned: bool) -> None:
    """What a description whose rows' periods were given wrong makes of a projector: fy 1.6x fx."""
    from rig.calibrate.boards import Board, Detection
    from rig.calibrate.report import report
    from rig.calibrate.solve import calibrate_cameras
    from rig.calibrate.views import View
    from rig.config.calibration import BoardConfig

    board = Board(BoardConfig(squares=(10, 7), square_mm=20.0))
    ids = np.arange(board.corner_count)
    K = np.array([[1800.0, 0, 640], [0, fy, 512], [0, 0, 1]])
    rng = np.random.default_rng(5)
    views = []
    for v in range(8):
        rvec = rng.uniform(-0.4, 0.4, 3) * [1, 1, 0.3]
        tvec = np.array([rng.uniform(-40, 40), rng.uniform(-30, 30), rng.uniform(700, 900)])
        points, _ = cv2.projectPoints(board.object_points(ids), rvec, tvec, K, np.zeros(5))
        views.append(View(v, {0: Detection(ids, points.reshape(-1, 2))}))
    device = calibrate_cameras(views, board, ["camera0"], [(1280, 1024)], "k1")[0]
    aspect = [w for w in report([device])["warnings"] if "fy is" in w]
    assert bool(aspect) == warned
    if warned:
        assert aspect[0].startswith("camera0: fy is 1.6x fx (2880.0 against 1800.0 px)")
