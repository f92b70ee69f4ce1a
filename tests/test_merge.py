"""Several projectors and cameras: the merged cloud of config/sim-multi.yaml against ground truth,
the intensity cue's overlap, ICP realignment of a drifted head, and viewpoint planning."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from rig.assembly import open_rig
from rig.cli import main
from rig.config import REPO_CONFIG_DIR, config_from_dict, load_config
from rig.evaluate.merged import evaluate_merge
from rig.geometry import CameraModel
from rig.opened_rig import Rig
from rig.pipeline.capture import CUE
from rig.pipeline.merge import compare_across_pairs, expected_error_mm, thin
from rig.pipeline.pointset import PointSet
from rig.pipeline.results import ScanResult
from rig.pipeline.scan import run_scan
from rig.store.ply import ply_bytes
from rig.store.scandir import read_scan_frames, write_scan


@pytest.fixture(scope="module")
def multi() -> Iterator[tuple[Rig, ScanResult, dict[str, Any]]]:
    with open_rig(load_config(REPO_CONFIG_DIR / "sim-multi.yaml")) as the_rig:
        result = run_scan(the_rig, keep_frames=True)
        yield the_rig, result, evaluate_merge(the_rig, result)


def test_the_merged_cloud_covers_more_than_any_pair_and_is_no_worse(multi: tuple[Rig, ScanResult, Any]) -> None:
    _, result, report = multi
    merged, pairs = report["merged"], report["pairs"]
    assert len(pairs) == 4
    assert merged["completeness"] > max(p["completeness"] for p in pairs.values())
    assert merged["completeness"] >= 0.99  # together the heads see all the box shows them
    assert merged["rms_mm"] <= min(p["rms_mm"] for p in pairs.values())
    assert merged["cross_pair_within_half_sampling"] < 0.02
    assert result.merge is not None and result.merge["redundant_removed"] > 0.3 * result.merge["points_in"]
    assert sum(result.merge["kept_per_pair"].values()) == len(result.cloud)  # type: ignore[attr-defined]


def test_the_intensity_cue_finds_the_overlap(multi: tuple[Rig, ScanResult, Any]) -> None:
    _, result, report = multi
    assert set(report["overlap_cue"]) == {"camera-left", "camera-right"}
    for camera, scores in report["overlap_cue"].items():
        assert scores["overlap_pixels_true"] > 10_000, camera  # the top face: both projectors light it
        assert scores["precision"] >= 0.9 and scores["recall"] >= 0.9, (camera, scores)
    assert result.frames_projected == 2 * 24 + 4  # two phase sets, then dark, each alone, both


def test_a_merged_scan_is_stored_and_reprocessed_with_its_overlap(
    multi: tuple[Rig, ScanResult, Any], tmp_path: Path
) -> None:
    from rig.pipeline.scan import reconstruct_frames
    from rig.progress import ProgressTracker

    the_rig, result, _ = multi
    folder = write_scan(the_rig, result, tmp_path / "scan", "20261121-000000-abcdef")
    manifest = json.loads((folder / "manifest.json").read_text())
    assert manifest["merge"]["points_out"] == len(result.cloud)
    assert set(manifest["files"]["overlap"]) == {"camera-left", "camera-right"}
    assert (folder / "overlap_camera-left.png").is_file()
    _, frames = read_scan_frames(folder)
    assert len(frames[(CUE, 0)]) == 4
    again = reconstruct_frames(the_rig, result.codec, frames, ProgressTracker(None))
    assert len(again.cloud) == len(result.cloud)
    assert all(np.array_equal(again.overlap[c], result.overlap[c]) for c in result.overlap)


def _moved(model: CameraModel, rotation: np.ndarray, shift: np.ndarray) -> CameraModel:
    """The device moved rigidly in the world by x -> rotation x + shift."""
    r = model.R @ rotation.T
    return CameraModel(model.width, model.height, model.K, r, model.t - r @ shift, model.dist, model.projection)


def test_icp_realigns_a_head_knocked_by_2_mm_and_half_a_degree() -> None:
    data = yaml.safe_load((REPO_CONFIG_DIR / "sim-multi.yaml").read_text())
    data["simulation"]["scene"] = {"kind": "mesh", "path": str(REPO_CONFIG_DIR / "meshes" / "blob.ply")}
    data["simulation"]["scene"].update(fit_size_mm=150.0, plane=False)  # a shape that pins all six motions
    axis = np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8])
    rotation = Rotation.from_rotvec(np.radians(0.5) * axis).as_matrix()
    shift = np.array([2.0, 0.0, 0.0])

    def head_one(refine: str, drift: bool) -> ScanResult:
        data["scan"]["merge"] = {"pairs": [[0, 0], [1, 1]], "refine": refine}  # a head: camera and its projector
        with open_rig(config_from_dict(data, "icp test")) as the_rig:
            if drift:  # what reconstruction believes; the simulated bench keeps the true geometry
                the_rig.camera_models[1] = _moved(the_rig.camera_models[1], rotation, shift)
                the_rig.projector_models[1] = _moved(the_rig.projector_models[1], rotation, shift)
            return run_scan(the_rig)

    calibrated = head_one("none", drift=False).pairs[1].points
    realigned = head_one("icp", drift=True)
    assert realigned.merge is not None
    found = realigned.merge["alignment"]["projector-right/camera-right"]  # type: ignore[index]
    assert found["rotation_deg"] == pytest.approx(0.5, abs=0.05)
    assert found["translation_mm"] == pytest.approx(2.0, abs=0.2)

    def displacement(points: PointSet) -> float:
        common, a, b = np.intersect1d(calibrated.pixel, points.pixel, return_indices=True)
        assert len(common) > 100_000
        return float(np.sqrt(np.mean(np.sum((calibrated.points[a] - points.points[b]) ** 2, axis=1))))

    assert displacement(head_one("none", drift=True).pairs[1].points) > 1.0  # so the drift is real
    assert displacement(realigned.pairs[1].points) < 0.2


def test_redundancy_removal_leaves_no_two_pairs_within_the_radius() -> None:
    rng = np.random.default_rng(1)
    a = np.stack(np.meshgrid(np.arange(0, 20, 0.5), np.arange(0, 20, 0.5)), -1).reshape(-1, 2)
    b = a[:600] + rng.uniform(-0.25, 0.25, (600, 2))  # a second pair over part of the same plane
    points = np.concatenate([np.c_[a, np.zeros(len(a))], np.c_[b, np.zeros(len(b))]])
    source = np.r_[np.zeros(len(a), int), np.ones(len(b), int)]
    score = np.r_[np.ones(len(a)), np.full(len(b), 2.0)]  # the second pair is better conditioned
    keep, _ = compare_across_pairs(points, source, score, 0.5)
    assert keep[len(a) :].all()  # the better pair keeps all its samples
    assert keep[: len(a)].sum() < len(a) - 500  # the other gives up the shared area
    kept, kept_source = points[keep], source[keep]
    from scipy.spatial import cKDTree

    pairs = cKDTree(kept).query_pairs(0.5, output_type="ndarray")
    assert not (kept_source[pairs[:, 0]] != kept_source[pairs[:, 1]]).any()
    thinned = thin(kept, score[keep], 1.0)
    cells = np.floor((kept[thinned] - kept.min(axis=0)) / 1.0).astype(int)
    assert len(np.unique(cells, axis=0)) == thinned.sum()  # one point per voxel


def test_a_camera_ray_along_the_column_plane_is_badly_conditioned() -> None:
    from rig.geometry import look_at_rotation

    def device(position: tuple[float, float, float]) -> CameraModel:
        r = look_at_rotation(np.array(position), np.zeros(3), np.array([0.0, 0.0, 1.0]))
        return CameraModel(800, 600, np.array([[1000, 0, 400], [0, 1000, 300], [0, 0, 1.0]]), r, -r @ position)

    point = PointSet(
        np.zeros((1, 3)), np.array([[0, 0, 1.0]], np.float32), np.zeros((1, 3), np.uint8), np.ones(1, np.float32),
        np.zeros(1, np.uint8), np.zeros(1, np.int64),
    )  # fmt: skip
    projector = device((-500.0, 0.0, 500.0))
    across = expected_error_mm(point, device((-500.0, 200.0, 500.0)), projector, "u")  # baseline across columns
    along = expected_error_mm(point, device((-500.0, 0.0, 700.0)), projector, "u")  # baseline along a column
    assert along[0] > 20 * across[0]


@pytest.mark.parametrize("scene", ["box", "sphere"])
def test_plan_views_gives_a_cover_the_simulator_confirms(scene: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "views", "--scene", scene, "--coverage", "0.95", "--confirm", "--json"]) == 0
    plan = json.loads(capsys.readouterr().out)
    assert plan["coverage"] >= 0.95
    assert plan["confirmed_coverage"] >= 0.95
    assert 2 <= len(plan["cameras"]) <= 10 and 1 <= len(plan["projectors"]) <= len(plan["cameras"])


def test_plan_views_checks_its_arguments(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "views", "--scene", "box", "--coverage", "1.5", "--max-angle", "95"]) == 2
    err = capsys.readouterr().err
    assert "--coverage: outside 0.05..1" in err and "--max-angle: outside 5..89" in err


def test_every_point_carries_its_pair_quality_and_triangulation_angle(multi: tuple[Rig, ScanResult, Any]) -> None:
    from tests.conftest import ply_vertex

    the_rig, result, _ = multi
    vertex = ply_vertex(ply_bytes(result.cloud))
    assert {"source", "quality", "angle"} <= set(vertex.dtype.names)
    for k, pair in enumerate(result.pairs):
        mine = vertex["source"] == k
        assert mine.any()
        camera, projector = the_rig.camera_models[pair.camera], the_rig.projector_models[pair.projector]
        point = np.array([vertex["x"][mine][0], vertex["y"][mine][0], vertex["z"][mine][0]], float)
        rays = [point - camera.center, point - projector.center]
        expected = np.degrees(np.arccos(np.dot(*rays) / np.linalg.norm(rays[0]) / np.linalg.norm(rays[1])))
        assert vertex["angle"][mine][0] == pytest.approx(expected, abs=0.01)
    assert np.isfinite(vertex["angle"]).all() and 5 < float(np.median(vertex["angle"])) < 120


@pytest.mark.parametrize("codec", ["gray", "radial"])
def test_where_each_pair_measured_the_merged_cloud_is_no_worse(codec: str) -> None:
    """Other codecs too: gray (quantised, ranked by measured local noise) and radial (both
    projector coordinates). Compared where each pair measured, since a pair that sees only the
    box top has an easier surface than the merged cloud as a whole."""
    with open_rig(load_config(REPO_CONFIG_DIR / "sim-multi.yaml").with_codec(codec)) as the_rig:
        report = evaluate_merge(the_rig, run_scan(the_rig))
    for name, pair in report["pairs"].items():
        assert pair["merged_rms_mm_here"] <= pair["rms_mm"], (codec, name, pair)
    assert report["merged"]["completeness"] > max(p["completeness"] for p in report["pairs"].values())


def test_icp_refuses_an_overlap_that_leaves_a_motion_free() -> None:
    from rig.pipeline.icp import AlignmentRefusedError, point_to_plane

    rng = np.random.default_rng(2)
    plane = np.c_[rng.uniform(-50, 50, (5000, 2)), np.zeros(5000)]
    up = np.tile([0.0, 0.0, 1.0], (5000, 1))
    with pytest.raises(AlignmentRefusedError, match="leaves a motion free"):
        point_to_plane(plane[:2500] + np.array([1.0, 0, 0.2]), up[:2500], plane[2500:], up[2500:], 5.0)
    with pytest.raises(AlignmentRefusedError, match="pair up"):
        point_to_plane(plane[:2500] + np.array([0, 0, 50.0]), up[:2500], plane[2500:], up[2500:], 5.0)


def test_the_cue_sees_overlap_where_the_all_lit_frame_clips() -> None:
    from rig.pipeline.overlap import overlap_from_cue

    dark = np.zeros((1, 3), np.uint8)
    left = np.array([[240, 240, 120]], np.uint8)
    right = np.array([[240, 0, 0]], np.uint8)
    both = np.array([[255, 240, 120]], np.uint8)  # the first pixel clips: its sum, 480, is lost
    assert overlap_from_cue([dark, left, right, both], 255, 0.08).tolist() == [[True, False, False]]


def test_pairs_that_leave_a_camera_out_store_without_its_depth(
    multi: tuple[Rig, ScanResult, Any], tmp_path: Path
) -> None:
    import dataclasses

    from rig.errors import ConfigError

    the_rig, result, _ = multi
    left_only = dataclasses.replace(result, pairs=[p for p in result.pairs if p.camera == 0])
    folder = write_scan(the_rig, left_only, tmp_path / "scan", "20261121-000000-abcdef")
    assert set(json.loads((folder / "manifest.json").read_text())["files"]["depth"]) == {"camera-left"}
    data = yaml.safe_load((REPO_CONFIG_DIR / "sim-multi.yaml").read_text())
    for pairs, problem in (([], "at least 1 item"), ([[0, 2]], "names no projector and camera")):
        data["scan"]["merge"] = {"pairs": pairs}
        with pytest.raises(ConfigError, match=problem):
            config_from_dict(data, "t")


def test_plan_views_takes_the_operators_candidate_poses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    poses = [[300, 0, 100], [-300, 0, 100], [0, 300, 100], [0, -300, 100], [0, 0, 350], [0, 0, -300]]
    path = tmp_path / "poses.yaml"
    path.write_text(yaml.safe_dump(poses))
    assert main(["plan", "views", "--scene", "box", "--poses", str(path), "--json"]) == 0
    plan = json.loads(capsys.readouterr().out)
    assert plan["candidates"] == 6 and plan["coverage"] >= 0.95
    assert all(c["position_mm"] in [[float(x) for x in p] for p in poses] for c in plan["cameras"])
    path.write_text("- [1, 2]\n")
    assert main(["plan", "views", "--scene", "box", "--poses", str(path)]) == 2
    assert "must list 1 to 5000 positions" in capsys.readouterr().err


def test_eval_prints_the_merged_cloud_beside_each_pair(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["eval", "--config", str(REPO_CONFIG_DIR / "sim-multi.yaml"), "--codec", "gray"]) == 0
    out = capsys.readouterr().out
    assert "merged here" in out and "projector-right/camera-left" in out
    assert "overlap cue, camera-left: precision" in out
    assert re.search(r"merge: \d+ -> \d+ points \(\d+ redundant, \d+ thinned\)", out)
    assert "{" not in out  # tables and lines, not Python dictionaries


@pytest.mark.parametrize("scale_mm", [0.3, 80.0, 1e7])  # the last: cells too many to pack, the rows' own unique
def test_the_visible_surface_keeps_the_first_point_of_each_cell(scale_mm: float) -> None:
    from rig.evaluate.merged import _first_in_each_cell

    points = np.random.default_rng(7).normal(size=(20_000, 3)) * scale_mm
    points[::5] = points[1::5]  # points sharing a cell: the first of them is kept
    _, expected = np.unique(np.floor(points / 1.0).astype(np.int64), axis=0, return_index=True)
    assert np.array_equal(_first_in_each_cell(points, 1.0), expected)
    assert len(_first_in_each_cell(points[:0], 1.0)) == 0
