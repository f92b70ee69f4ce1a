"""Colour between the rings: the bench's textures and their truth, the interpolants, the metrics,
and the coloured mesh a ring scan writes."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import plyfile
import pytest
from conftest import small_config_data, write_config
from scipy.spatial import cKDTree

from drivers.sim.texture import Checker, Decal, Stripes
from rig.assembly import open_rig
from rig.cli import main
from rig.config import config_from_dict, load_config
from rig.errors import ConfigError
from rig.evaluate.colour import albedo_errors, colour_metrics, delta_e2000
from rig.pipeline.colour import COLOUR_METHODS, _along_rings, interpolate_colour, sample_colours
from rig.pipeline.dense import texture_rgb
from rig.pipeline.scan import run_scan
from rig.pipeline.surface import RingSurface

GRADIENT = {"kind": "gradient", "period_mm": 120.0}


def textured(texture: dict[str, Any], rings: int = 12, **surface: Any) -> dict[str, Any]:
    data = small_config_data()
    data["simulation"]["texture"] = texture
    data["cameras"][0]["color"] = True
    data["scan"]["codec"] = "rings"
    data["scan"]["rings"] = {"rings": rings}
    data["scan"]["surface"] = {"mesh_stride_px": 1, **surface}
    return data


@pytest.fixture(scope="module")
def gradient_scan():  # type: ignore[no-untyped-def]
    with open_rig(config_from_dict(textured(GRADIENT), "gradient")) as rig:
        result = run_scan(rig)
        yield rig, result.pairs[0]


def with_colour(pair: Any, method: str, neighbours: int = 8) -> Any:
    rings, corr = pair.rings, pair.correspondence
    colours = sample_colours(corr.texture, rings.camera_xy[rings.kept], corr.full_scale)
    colour = interpolate_colour(pair.surface, colours, method, neighbours)  # type: ignore[arg-type]
    return dataclasses.replace(pair, surface=dataclasses.replace(pair.surface, colour=colour))


def test_a_checker_on_the_bench_plane_is_one_colour_per_square() -> None:
    checker = Checker(10.0, ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
    rng = np.random.default_rng(0)
    xy = rng.uniform(1.0, 4.0, (200, 2))  # inside one square
    noisy_z = rng.normal(0.0, 1e-9, 200)  # the bench plane, as ray casting delivers it
    colours = checker.colour_at(np.column_stack([xy, noisy_z]))
    assert (colours == colours[0]).all()
    neighbour = checker.colour_at(np.array([[7.0, 2.0, 0.0]]))  # the next square along x
    assert not np.array_equal(neighbour[0], colours[0])


def test_stripes_and_a_decal_give_their_colours_where_they_should() -> None:
    stripes = Stripes(30.0, (1.0, 0.0, 0.0), ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)))
    found = stripes.colour_at(np.array([[0.0, 40.0, 3.0], [10.0, -8.0, 0.0], [20.0, 0.0, 9.0], [30.0, 0.0, 0.0]]))
    assert found.argmax(axis=1).tolist() == [0, 1, 2, 0]
    image = np.zeros((2, 2, 3), np.float32)
    image[0, 0], image[1, 1] = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)  # top-left red, bottom-right blue
    decal = Decal(image, size_mm=100.0, center_mm=(0.0, 0.0))
    corners = decal.colour_at(np.array([[-40.0, 40.0, 5.0], [40.0, -40.0, 0.0]]))  # +y is the image's top
    assert corners[0].argmax() == 0 and corners[1].argmax() == 2


def test_the_true_albedo_is_what_the_white_frame_shows(gradient_scan) -> None:  # type: ignore[no-untyped-def]
    rig, pair = gradient_scan
    truth = rig.truth.ground_truth(0, 0)
    white = texture_rgb(pair.correspondence).astype(np.float64) / 255.0
    seen = truth.hit & truth.lit & (truth.white_irradiance > 0.3)
    ratio = white[seen] / (truth.albedo[seen] * truth.white_irradiance[seen][:, None])
    spread = np.percentile(ratio, [5, 95], axis=0) / np.median(ratio)
    assert np.all(spread[0] > 0.93) and np.all(spread[1] < 1.07), spread  # one exposure gain, noise aside


def test_weighted_colour_beats_the_nearest_samples_and_the_white_frame_beats_both(gradient_scan) -> None:  # type: ignore[no-untyped-def]
    rig, pair = gradient_scan
    truth = rig.truth.ground_truth(0, 0)
    psnr = {m: colour_metrics(with_colour(pair, m), truth)["colour_psnr_db"] for m in COLOUR_METHODS}
    white = colour_metrics(with_colour(pair, "idw"), truth)["white_colour_psnr_db"]
    assert psnr["idw"] > psnr["nearest"] + 2.0 and psnr["area"] > psnr["nearest"] + 2.0, psnr
    assert white > max(psnr.values()) + 5.0
    assert psnr["idw"] > 25.0  # a smooth texture, 12 rings: the colour between them is close


def test_interpolated_colour_of_a_uniform_colour_is_that_colour_everywhere(gradient_scan) -> None:  # type: ignore[no-untyped-def]
    _, pair = gradient_scan
    samples = np.tile(np.array([[0.2, 0.5, 0.7]], np.float32), (len(pair.surface.vertices), 1))
    for method in COLOUR_METHODS:
        colour = interpolate_colour(pair.surface, samples, method)  # type: ignore[arg-type]
        covered = pair.surface.valid
        assert np.isfinite(colour[covered]).all() and not np.isfinite(colour[~covered]).any()
        assert np.allclose(colour[covered], [0.2, 0.5, 0.7], atol=1e-5)
    with pytest.raises(ValueError, match="unknown colour interpolant 'bicubic'"):
        interpolate_colour(pair.surface, samples, "bicubic")  # type: ignore[arg-type]


def nearest_on_each_ring(vertices: np.ndarray, faces: np.ndarray, ring: np.ndarray, count: int) -> list[set[int]]:
    """Each sample's `count` nearest samples of its own ring among those in a face, by brute force
    (none for a sample in no face)."""
    used = np.zeros(len(vertices), bool)
    used[faces.ravel()] = True
    found: list[set[int]] = []
    for n in range(len(vertices)):
        mates = np.flatnonzero(used & (ring == ring[n])) if used[n] else np.array([], int)
        distance = np.linalg.norm(vertices[mates] - vertices[n], axis=1)
        found.append(set(mates[np.argsort(distance, kind="stable")[:count]].tolist()))
    return found


def test_each_samples_neighbours_along_its_ring_are_its_nearest_there(gradient_scan) -> None:  # type: ignore[no-untyped-def]
    """The candidates a face's pixels take colour from: on the scan's own rings, and on random rings
    folded back on themselves (a sweep along one axis meets the fold's far side first)."""
    _, pair = gradient_scan
    rng = np.random.default_rng(5)
    angle = rng.uniform(0, 4 * np.pi, 400)
    folded = np.column_stack([np.cos(angle) * (1 + angle), np.sin(2 * angle), angle % 0.3])
    cases = [pair.surface, (folded, rng.integers(0, 400, (300, 3)), rng.integers(0, 5, 400))]
    for case in cases:
        surface = case if isinstance(case, RingSurface) else _with_samples(pair.surface, *case)
        along = _along_rings(surface.vertices, surface.faces, surface.ring, 8)
        subset = np.arange(0, len(surface.vertices), max(1, len(surface.vertices) // 1500))
        truth = nearest_on_each_ring(surface.vertices, surface.faces, surface.ring, along.shape[1])
        for n in subset:
            listed = set(along[n][along[n] < len(surface.vertices)].tolist())
            assert listed == truth[n], n
            distance = np.linalg.norm(surface.vertices[along[n][: len(listed)]] - surface.vertices[n], axis=1)
            assert (np.diff(distance) >= 0).all()  # nearest first


def _with_samples(surface: RingSurface, vertices: np.ndarray, faces: np.ndarray, ring: np.ndarray) -> RingSurface:
    return dataclasses.replace(surface, vertices=vertices, faces=faces, ring=ring)


def test_colour_does_not_cross_a_depth_edge() -> None:
    """Steps whose treads are painted different colours (bands along z, 5 mm each): next to a
    riser, where the surface is right, a tread keeps its own colour."""
    colours = [(0.9, 0.1, 0.1), (0.1, 0.8, 0.2), (0.1, 0.2, 0.9), (0.9, 0.9, 0.2)] * 4
    texture = {"kind": "stripes", "period_mm": 80.0, "direction_mm": [0, 0, 1], "colours": colours}
    data = textured(texture, rings=16, colour="idw")
    data["simulation"]["scene"] = {"kind": "steps", "rises_mm": [10.0, 15.0, 20.0], "run_mm": 40.0}
    with open_rig(config_from_dict(data, "steps")) as rig:
        pair = run_scan(rig).pairs[0]
        truth = rig.truth.ground_truth(0, 0)
    flat = truth.hit & truth.lit & (np.abs(truth.normals[..., 2]) > 0.99)  # treads and the bench plane
    height = np.where(truth.hit, truth.points[..., 2], -100.0).astype(np.float32)
    window = np.ones((9, 9), np.uint8)
    near_riser = cv2.dilate(height, window) - cv2.erode(height, window) > 5.0  # within 4 px of a depth edge
    placed = np.linalg.norm(pair.surface.grid - truth.points, axis=2) < 1.0  # where the surface itself is wrong,
    coloured = np.isfinite(pair.surface.colour).all(axis=2)  # so is where its colour comes from
    overall = albedo_errors(pair.surface.colour, truth, flat & coloured)
    at_edges = albedo_errors(pair.surface.colour, truth, flat & coloured & near_riser & placed)
    assert (flat & coloured & near_riser & placed).sum() > 300
    assert overall["rgb_rms"] < 0.06 and at_edges["rgb_rms"] < 0.04, (overall, at_edges)


def test_delta_e2000_matches_sharma_wu_dalals_test_pairs() -> None:
    pairs = np.array(
        [
            [50.0, 2.6772, -79.7751, 50.0, 0.0, -82.7485, 2.0425],
            [50.0, -1.3802, -84.2814, 50.0, 0.0, -82.7485, 1.0000],
            [50.0, 2.5, 0.0, 73.0, 25.0, -18.0, 27.1492],
            [50.0, 2.5, 0.0, 61.0, -5.0, 29.0, 22.8977],
            [84.25, 5.74, 96.0, 84.46, 8.88, 96.49, 1.6743],
        ]
    )
    assert np.allclose(delta_e2000(pairs[:, :3], pairs[:, 3:6]), pairs[:, 6], atol=1e-4)
    assert np.allclose(delta_e2000(pairs[:, 3:6], pairs[:, :3]), pairs[:, 6], atol=1e-4)  # symmetric


def test_a_ring_scan_with_interpolated_colour_writes_a_coloured_mesh(tmp_path: Path) -> None:
    chart = Path(__file__).resolve().parent.parent / "config/textures/chart.png"
    data = textured({"kind": "image", "path": str(chart), "size_mm": 240.0}, rings=16, colour="area")
    data["scan"]["surface"]["mesh_stride_px"] = 2
    out = tmp_path / "scan"
    assert main(["scan", "--config", str(write_config(tmp_path, data)), "--out", str(out)]) == 0
    vertex = plyfile.PlyData.read(out / "mesh.ply")["vertex"].data
    rgb = np.column_stack([vertex["red"], vertex["green"], vertex["blue"]]).astype(float)
    assert rgb.std(axis=0).min() > 10  # the chart's colours, not one grey
    cloud = plyfile.PlyData.read(out / "cloud.ply")["vertex"].data  # the ring samples, white-frame colours
    _, nearest = cKDTree(np.column_stack([cloud["x"], cloud["y"], cloud["z"]])).query(
        np.column_stack([vertex["x"], vertex["y"], vertex["z"]])
    )
    white = np.column_stack([cloud["red"], cloud["green"], cloud["blue"]]).astype(float)[nearest]
    # the colour between the rings follows the nearest ring's (a red-blue swap or a shifted image would not)
    assert np.median(np.abs(rgb - white).mean(axis=1)) < 20


def test_a_texture_image_that_is_missing_is_refused_by_name(tmp_path: Path) -> None:
    data = textured({"kind": "image", "path": "no-such.png"})
    with pytest.raises(ConfigError, match=r"simulation\.texture\.path: image file not found"):
        load_config(write_config(tmp_path, data))
