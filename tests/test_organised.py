"""The organised fast path (rig.pipeline.organised) against the general one (rig.pipeline.dense):
the same points, normals, colours and rejections."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from rig.assembly import open_rig
from rig.config import config_from_dict
from rig.pipeline.dense import pair_pointset, reject_isolated
from rig.pipeline.scan import capture, make_codec, pair_cloud, reconstruct_pair, triangulator
from rig.progress import ProgressTracker
from tests.conftest import small_config_data

# float32 coordinates relative to the camera centre against float64 world coordinates: the
# difference is float32 rounding (a PLY stores float32 anyway).
POINT_TOLERANCE_MM = 1e-3
NORMAL_TOLERANCE = 1e-3


_NORMAL_REACH = 2  # pixels: the neighbours grid_normals spans a point's tangent plane with


def _at_the_limit(grid: np.ndarray, model: Any, jump: float) -> np.ndarray:
    """Pixels with a neighbour whose depth differs by the depth-jump limit within the paths'
    rounding: float32 rays against float64 ones decide these either way."""
    depth = (grid - model.center) @ model.axis
    near = np.zeros(depth.shape, bool)
    padded = np.pad(depth, 1, constant_values=np.nan)
    h, w = depth.shape
    with np.errstate(invalid="ignore"):
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                step = np.abs(depth - padded[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w])
                near |= np.abs(step - jump) <= POINT_TOLERANCE_MM
    return near


def _dilated(mask: np.ndarray, reach: int) -> np.ndarray:
    grown = mask.copy()
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            grown |= np.roll(mask, (dy, dx), axis=(0, 1))
    return grown


def _small(codec: str, **scan: Any) -> dict[str, Any]:
    data = small_config_data()
    data["scan"]["codec"] = codec
    data["scan"].update(scan)
    return data


@pytest.mark.parametrize(
    ("codec", "jump", "scan"),
    [
        ("phase", 2.0, {}),
        ("gray", 2.0, {}),
        ("phase", None, {}),
        ("radial", 2.0, {}),  # both coordinates: a ray meets a ray
        ("gray", None, {"gray": {"directions": "both"}}),
    ],
)
def test_the_fast_path_gives_the_general_paths_cloud(codec: str, jump: float | None, scan: dict[str, Any]) -> None:
    config = config_from_dict(_small(codec, max_depth_jump_mm=jump, **scan), "organised-test")
    with open_rig(config) as rig:
        codec_ = make_codec(rig, 0)
        corr = codec_.decode(capture(rig, [codec_], ProgressTracker(None))[(0, 0)], 255)
        found = pair_cloud(rig, 0, 0, corr)
        assert found is not None
        cloud, counts = found
        model = rig.camera_models[0]
        grid, valid = triangulator(rig, 0, 0).triangulate(corr)  # the general path's own
        borderline = np.zeros_like(valid)
        if jump is not None:
            keep = reject_isolated(grid, valid, model, jump)
            borderline = _at_the_limit(grid, model, jump)
            assert counts["rejected_depth_jump"] == pytest.approx(int((valid & ~keep).sum()), abs=int(borderline.sum()))
            assert counts["rejected_depth_jump"] > 0
            grid[valid & ~keep] = np.nan
            valid = keep
        reference = pair_pointset(grid, valid, model, corr, source=3)
    differs = cloud.valid != valid
    assert not (differs & ~borderline).any()
    assert differs.sum() <= 0.001 * valid.sum()
    same = ~_dilated(differs, _NORMAL_REACH)  # a normal's neighbours: the same points
    np.testing.assert_allclose(cloud.grid()[same], grid[same], atol=POINT_TOLERANCE_MM)
    got = cloud.into_pointset(source=3)
    assert len(got) == pytest.approx(len(reference), abs=int(differs.sum())) and len(reference) > 10_000
    at_got = np.isin(got.pixel, np.flatnonzero(same))
    at_reference = np.isin(reference.pixel, np.flatnonzero(same))
    np.testing.assert_array_equal(got.pixel[at_got], reference.pixel[at_reference])
    assert float(np.abs(got.points[at_got] - reference.points[at_reference]).max()) < POINT_TOLERANCE_MM
    assert float(np.abs(got.normals[at_got] - reference.normals[at_reference]).max()) < NORMAL_TOLERANCE
    for name in ("colors", "quality", "source", "pixel"):
        np.testing.assert_array_equal(getattr(got, name)[at_got], getattr(reference, name)[at_reference])
    with pytest.raises(RuntimeError, match="already made into its PointSet"):
        cloud.into_pointset(source=3)  # its images are gone: a second PointSet would be empty


@pytest.mark.parametrize("codec", ["gray", "radial"])
def test_pairs_the_fast_path_does_not_cover_take_the_general_path(codec: str) -> None:
    distorted_data = _small(codec)
    distorted_data["projectors"][0]["geometry"]["distortion"] = [0.05, 0.0, 0.0, 0.0, 0.0]
    distorted = config_from_dict(distorted_data, "organised-distorted")
    for config in (distorted,):
        with open_rig(config) as rig:
            codec = make_codec(rig, 0)
            corr = codec.decode(capture(rig, [codec], ProgressTracker(None))[(0, 0)], 255)
            assert pair_cloud(rig, 0, 0, corr) is None
            assert len(reconstruct_pair(rig, 0, 0, corr, source=0).points) > 10_000


def test_a_ray_that_runs_in_its_plane_is_no_point_and_no_error() -> None:
    """A camera whose baseline to the projector runs along the coded planes (or a pixel whose ray
    does, exactly): the plane meets the ray nowhere, a zero denominator, which must not raise."""
    from rig.kernels import dense

    shape = (2, 3)
    image = np.ones(shape, np.float32)
    zero = np.zeros(shape, np.float32)
    c = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 2.0]], np.float32)  # denominator c + d u: 0 where c is
    ray, depth = np.empty(shape, np.float32), np.empty(shape, np.float32)
    decoded = np.empty(shape, bool)
    dense.plane_triangulate(
        image, np.ones(shape, bool), (np.float32(1.0), np.float32(0.0)), c, zero, np.float32(0.0), np.float32(0.0),
        image,
        ray, depth, decoded, 0, shape[0],
    )  # fmt: skip
    assert decoded.tolist() == [[False, True, False], [True, False, True]]
    assert np.isnan(ray[c == 0]).all() and np.allclose(ray[c != 0], 1.0 / c[c != 0])


def test_plane_terms_hold_a_and_b_as_numbers_and_refuse_rays_from_several_points() -> None:
    """The fast path's a and b are the same at every pixel of a camera whose rays all leave its
    centre: two numbers, not two images; terms from rays that leave from more than one point are
    refused rather than read at their first pixel."""
    from rig.geometry import CameraModel
    from rig.pipeline.organised import PlaneTerms

    camera = CameraModel(40, 30, np.array([[50.0, 0, 19.5], [0, 50.0, 14.5], [0, 0, 1]]), np.eye(3), np.zeros(3))
    size = camera.width * camera.height
    varying = np.linspace(1.0, 2.0, size)
    terms = (np.ones(size), np.full(size, 0.1), np.full(size, 3.0), np.full(size, 0.5), 7.0, 2.0)
    planes = PlaneTerms(camera, "u", terms, 0.01, -0.5)
    assert np.ndim(planes.a) == 0 and np.ndim(planes.b) == 0
    assert planes.a == np.float32(7.0 - 3.0 + (2.0 - 0.5) * -0.5) and planes.b == np.float32((2.0 - 0.5) * 0.01)
    with pytest.raises(ValueError, match="more than one point"):
        PlaneTerms(camera, "u", (*terms[:2], varying, *terms[3:]), 0.01, -0.5)


@pytest.mark.parametrize(("codec", "jump"), [("phase", 2.0), ("gray", 0.5), ("phase", None)])
def test_the_depth_image_in_one_pass_is_the_three_passes_depth_to_the_bit(codec: str, jump: float | None) -> None:
    """Live mode's depth image of a pair of coded planes, triangulated, tested for isolated points
    and blanked in one pass per band of rows (rig.kernels.depth): the same depths and count as the
    three passes, on strips of any height down to one row."""
    from rig.pipeline.organised import PixelTerms, PlaneTerms, fast_terms

    config = config_from_dict(_small(codec, max_depth_jump_mm=jump), "organised-depth")
    with open_rig(config) as rig:
        codec_ = make_codec(rig, 0)
        corr = codec_.decode(capture(rig, [codec_], ProgressTracker(None))[(0, 0)], 255)
        terms = fast_terms(triangulator(rig, 0, 0), "u")
    assert isinstance(terms, PlaneTerms)
    expected, count = PixelTerms.depth(terms, corr, jump)  # the three passes
    assert count > 1000 and np.isnan(expected).any()
    found, found_count = terms.depth(corr, jump)
    assert found_count == count and np.array_equal(found, expected, equal_nan=True)
    from rig.kernels import depth as depth_kernels

    one_row_at_a_time = np.empty_like(expected)
    limits = (jump is not None, np.float32(jump or 0.0), 3)
    plane = (corr.u, corr.valid, (terms.a, terms.b, terms.scale, terms.shift), terms.c, terms.d, terms.along_axis)
    rows = range(len(expected))
    assert sum(depth_kernels.plane_depth(plane, limits, one_row_at_a_time, y, y + 1) for y in rows) == count
    assert np.array_equal(one_row_at_a_time, expected, equal_nan=True)
