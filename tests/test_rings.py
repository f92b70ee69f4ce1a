"""Concentric rings and radial fringes: decoding, localisation, ray-cone, and measured accuracy."""

from __future__ import annotations

import json
from collections.abc import Iterator

import cv2
import numpy as np
import pytest

from rig.assembly import open_rig
from rig.cli import main
from rig.config import config_from_dict, load_config
from rig.geometry.cone import ray_cone
from rig.opened_rig import Rig
from rig.patterns import codec_class
from rig.patterns.radial import RadialParams
from rig.patterns.rings import RingsParams
from rig.pipeline.results import PairResult
from rig.pipeline.scan import make_codec, run_scan
from tests.conftest import UNCLIPPED_FULL_SCALE, make_device, unclipped

SIZE = (1024, 768)


def _radial_distance(xy: np.ndarray, center: tuple[float, float]) -> np.ndarray:
    return np.hypot(xy[:, 0] - center[0], xy[:, 1] - center[1])


@pytest.mark.parametrize(
    "params",
    [RingsParams(), RingsParams(rings=7, radii_px=[20, 45, 80, 130, 200, 290, 400], center_px=(300.0, 500.0))],
)
def test_ring_index_and_position_noise_free(params: RingsParams) -> None:
    codec = codec_class("rings")(SIZE, params)
    samples = codec.decode(unclipped(codec.patterns()), UNCLIPPED_FULL_SCALE).samples
    assert samples is not None
    radius = _radial_distance(samples.camera_xy, samples.center_px)
    nearest_ring = np.argmin(np.abs(radius[:, None] - codec.radii[None, :]), axis=1)
    np.testing.assert_array_equal(samples.ring, nearest_ring)
    assert np.max(np.abs(radius - samples.radius_px)) <= 0.05
    theta = np.arctan2(samples.camera_xy[:, 1] - samples.center_px[1], samples.camera_xy[:, 0] - samples.center_px[0])
    assert np.max(np.abs(np.angle(np.exp(1j * (samples.theta - theta))))) < 0.02
    # every ring that fits in the image is found
    cu, cv = samples.center_px
    inside = [
        k
        for k, r in enumerate(codec.radii)
        if cu - r > 2 and cu + r < SIZE[0] - 3 and cv - r > 2 and cv + r < SIZE[1] - 3
    ]
    assert set(inside) <= set(samples.ring.tolist())


@pytest.mark.parametrize("shift", [0.0, 0.31, -0.43])
def test_ring_localisation_through_blur_and_subpixel_shift(shift: float) -> None:
    """The camera sees the projector shifted by a fraction of a pixel and blurred; the zero crossing
    of pattern - inverse still lands on the circle within 0.05 px. The innermost ring (16 px) is left
    out: blur pulls a curved edge inward by about sigma^2 / 2R (0.015 px there), which with this
    test's own bilinear resampling adds up to just over 0.05."""
    codec = codec_class("rings")(SIZE)
    h, w = SIZE[1], SIZE[0]
    map_x, map_y = np.meshgrid(np.arange(w, dtype=np.float32) + shift, np.arange(h, dtype=np.float32) + shift / 2)
    frames = []
    for pattern in codec.patterns():
        image = cv2.remap(pattern.astype(np.float32), map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        frames.append(np.rint(cv2.GaussianBlur(image, (0, 0), 0.7)).astype(np.uint8))
    samples = codec.decode(unclipped(frames), UNCLIPPED_FULL_SCALE).samples
    assert samples is not None and len(samples) > 10000
    projector_xy = samples.camera_xy + np.array([shift, shift / 2])
    error = _radial_distance(projector_xy, samples.center_px) - samples.radius_px
    xy = samples.camera_xy  # the blur's image border is the test harness's, not the codec's
    inner = (xy[:, 0] > 3) & (xy[:, 0] < w - 4) & (xy[:, 1] > 3) & (xy[:, 1] < h - 4) & (samples.ring > 0)
    assert np.max(np.abs(error[inner])) <= 0.05


def test_ray_cone_against_analytic_cones() -> None:
    camera = make_device(320, 256, 450.0, (-100.0, 0.0, 600.0), (0.0, 0.0, 30.0))
    for projector in (
        make_device(256, 192, 375.0, (100.0, 0.0, 620.0), (0.0, 0.0, 30.0)),
        make_device(256, 192, 0.8, (0.0, 0.0, 600.0), projection="orthographic"),
    ):
        points = np.random.default_rng(5).uniform([-60, -60, 0], [60, 60, 80], (3000, 3))
        uv, _ = camera.project(points)
        origins, directions = camera.rays(uv)
        center = (120.0, 90.0)
        puv, _ = projector.project(points)
        radius = np.hypot(puv[:, 0] - center[0], puv[:, 1] - center[1])
        hits = ray_cone(projector, np.ascontiguousarray(origins), directions, radius, center)
        error = np.linalg.norm(hits.points - points[:, None, :], axis=2)
        assert np.all(np.nanmin(error, axis=1) < 1e-6)  # one root is the point
        for k in range(2):  # and every root lies on the ring's cone
            ok = np.isfinite(hits.s[:, k])
            ruv, _ = projector.project(hits.points[ok, k])
            np.testing.assert_allclose(np.hypot(ruv[:, 0] - center[0], ruv[:, 1] - center[1]), radius[ok], atol=1e-6)


def test_the_root_the_decoded_angle_picks_is_the_true_point_and_its_terms_are_the_cones() -> None:
    """rig.kernels.ring_points.chosen_roots over ray_cone's roots: with the true angle, the chosen
    root is the point and the other root is the rejected one; a decoded angle off both roots by
    more than MAX_ANGLE_ERROR_RAD finds none. ConeHits.terms is each ray's image about the centre."""
    from rig.geometry.cone import affine_image
    from rig.kernels.ring_points import chosen_roots
    from rig.pipeline.ring_triangulation import MAX_ANGLE_ERROR_RAD

    camera = make_device(320, 256, 450.0, (-100.0, 0.0, 600.0), (0.0, 0.0, 30.0))
    projector = make_device(256, 192, 375.0, (100.0, 0.0, 620.0), (0.0, 0.0, 30.0))
    points = np.random.default_rng(6).uniform([-60, -60, 0], [60, 60, 80], (2000, 3))
    origins, directions = camera.rays(camera.project(points)[0])
    origins, directions = (
        np.ascontiguousarray(np.broadcast_to(origins, directions.shape)),
        np.ascontiguousarray(directions),
    )
    center = (120.0, 90.0)
    puv, _ = projector.project(points)
    radius = np.hypot(puv[:, 0] - center[0], puv[:, 1] - center[1])
    theta = np.arctan2(puv[:, 1] - center[1], puv[:, 0] - center[0])
    theta[::7] += np.pi  # half a turn off: at most the other root's angle
    hits = ray_cone(projector, origins, directions, radius, center)
    alpha, beta = affine_image(projector, origins, directions)
    np.testing.assert_allclose(hits.terms[:, 2], alpha[:, 2])
    np.testing.assert_allclose(hits.terms[:, 5], beta[:, 2])
    np.testing.assert_allclose(hits.terms[:, 0], alpha[:, 0] - center[0] * alpha[:, 2])
    count = len(points)
    found, sigma, cos_beta = np.empty(count, bool), np.empty(count), np.empty(count)
    chosen, other = np.empty((count, 3)), np.empty((count, 3))
    roots = (hits.s, hits.theta, hits.ds_dradius, hits.cos_beta)
    chosen_roots(
        roots,
        theta,
        (origins, directions),
        (0.05, MAX_ANGLE_ERROR_RAD),
        (found, chosen, other, sigma, cos_beta),
        0,
        count,
    )
    error = np.abs(np.angle(np.exp(1j * (hits.theta - theta[:, None]))))
    error[~np.isfinite(hits.s)] = np.inf
    expected = error.min(axis=1) <= MAX_ANGLE_ERROR_RAD
    np.testing.assert_array_equal(found, expected)
    assert found.mean() > 0.8 and found[::7].mean() < 0.5
    far = np.linalg.norm(chosen[::7] - points[::7], axis=1) > 1.0  # half a turn off: never the true point
    assert far[found[::7]].all()
    true = np.ones(count, bool)
    true[::7] = False
    np.testing.assert_allclose(chosen[true & found], points[true & found], atol=1e-6)
    k = np.argmin(error, axis=1)
    rows = np.arange(count)
    np.testing.assert_array_equal(sigma, np.abs(hits.ds_dradius[rows, k]) * 0.05)
    np.testing.assert_array_equal(cos_beta, np.nan_to_num(hits.cos_beta[rows, k], nan=0.0))
    np.testing.assert_array_equal(other, hits.points[rows, 1 - k])


def test_radial_decodes_radius_and_angle_noise_free() -> None:
    codec = codec_class("radial")(SIZE, RadialParams())
    corr = codec.decode(unclipped(codec.patterns()), UNCLIPPED_FULL_SCALE)
    v, u = np.mgrid[0 : SIZE[1], 0 : SIZE[0]]
    cu, cv = codec.center
    assert corr.valid.mean() > 0.99
    ok = corr.valid
    radius = np.hypot(u - cu, v - cv)
    assert np.max(np.abs(corr.extra["radius"][ok] - radius[ok])) <= 0.05
    tangential = np.angle(np.exp(1j * (corr.extra["theta"] - np.arctan2(v - cv, u - cu)))) * radius
    assert np.max(np.abs(tangential[ok])) <= 0.05
    assert np.max(np.abs(corr.u[ok] - u[ok])) <= 0.05 and np.max(np.abs(corr.v[ok] - v[ok])) <= 0.05


@pytest.fixture(scope="module")
def ring_scan() -> Iterator[tuple[Rig, PairResult, np.ndarray]]:
    config = load_config().with_codec("rings")
    with open_rig(config) as the_rig:
        result = run_scan(the_rig)
        radii = make_codec(the_rig, 0).radii
        yield the_rig, result.pairs[0], radii


@pytest.fixture(scope="module")
def classic_ring_scan() -> Iterator[tuple[Rig, PairResult]]:
    """Rings without the fine angular code: the radius alone places the points."""
    data = load_config().with_codec("rings").model_dump(mode="json")
    data["scan"]["rings"]["tangential_period_px"] = None
    with open_rig(config_from_dict(data, "classic rings")) as the_rig:
        yield the_rig, run_scan(the_rig).pairs[0]


def test_rings_every_ring_on_the_object_yields_points(ring_scan: tuple[Rig, PairResult, np.ndarray]) -> None:
    the_rig, pair, radii = ring_scan
    assert the_rig.truth is not None and pair.rings is not None
    assert len(radii) == 32
    truth = the_rig.truth.ground_truth(0, 0)
    center = np.array([0.0, 0.0, 60.0])  # the default scene's sphere
    on_sphere = truth.hit & truth.lit & (np.abs(np.linalg.norm(truth.points - center, axis=2) - 60.0) < 0.01)
    on_sphere &= truth.points[..., 2] > 5.0
    rho = np.hypot(*(truth.projector_uv[on_sphere] - [511.5, 383.5]).T)
    crossing = {k for k, r in enumerate(radii) if np.any(np.abs(rho - r) < 0.5)}
    assert len(crossing) >= 5
    rp = pair.rings
    kept_on_sphere = rp.kept & (np.abs(np.linalg.norm(rp.points - center, axis=1) - 60.0) < 1.0)
    assert crossing <= set(rp.ring[kept_on_sphere].tolist())


def test_rings_never_choose_the_wrong_root(ring_scan: tuple[Rig, PairResult, np.ndarray]) -> None:
    the_rig, pair, _ = ring_scan
    rp = pair.rings
    assert the_rig.truth is not None and rp is not None
    true, _ = the_rig.truth.cast(rp.origins, rp.directions)
    chosen = np.linalg.norm(rp.points - true, axis=1)
    other = np.linalg.norm(rp.other_root - true, axis=1)
    two_roots = np.isfinite(other)
    assert two_roots[rp.kept].mean() > 0.5  # the layout is off-axis: most rays meet the cone twice
    checked = rp.kept & two_roots
    assert np.all(chosen[checked] < other[checked])
    # The only wrong choices are masked near-tangent rays, where both roots have the same angle.
    wrong = two_roots & (chosen >= other)
    assert np.all(rp.cos_beta[wrong] < 0.05)


def test_rings_masking_removes_the_ill_conditioned_points(classic_ring_scan: tuple[Rig, PairResult]) -> None:
    the_rig, pair = classic_ring_scan
    rp = pair.rings
    assert the_rig.truth is not None and rp is not None
    true, normal = the_rig.truth.cast(rp.origins, rp.directions)
    error = np.abs(np.einsum("ij,ij->i", rp.points - true, normal))
    masked = ~rp.kept
    assert pair.counts["masked_ill_conditioned"] == int((masked & (rp.cos_beta < 0.3)).sum()) > 1000
    assert np.median(error[masked]) > 3 * np.median(error[rp.kept])
    # the per-point uncertainty ranks the errors
    sigma = rp.sigma_mm[rp.kept]
    low, high = np.quantile(sigma, [0.25, 0.75])
    assert np.median(error[rp.kept][sigma >= high]) > 1.5 * np.median(error[rp.kept][sigma <= low])


def test_rings_accuracy_and_manifest_counts(capsys: pytest.CaptureFixture[str], tmp_path) -> None:  # type: ignore[no-untyped-def]
    assert main(["eval", "--codec", "rings", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["rms_mm"] <= 0.20
    assert report["points"] == report["counts"]["ring_points"]
    assert main(["scan", "--codec", "rings", "--out", str(tmp_path / "rings"), "--json"]) == 0
    manifest = json.loads((tmp_path / "rings" / "manifest.json").read_text())
    counts = manifest["pairs"][0]["counts"]
    assert counts["fixed_by_angle"] > 1000  # the samples the radius alone would have masked
    assert counts["ring_points"] == manifest["economy"]["points"] == report["points"]
    assert manifest["economy"]["frames_projected"] == 22
    coverage = manifest["pairs"][0]["ring_coverage"]
    assert coverage["min_ring"] >= 0.9 and coverage["overall"] >= 0.95
    assert min(coverage["rings"].values()) == coverage["min_ring"] and len(coverage["rings"]) >= 25


def test_radial_against_phase_at_the_same_frame_count(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["eval", "--codec", "radial", "--json"]) == 0
    radial = json.loads(capsys.readouterr().out)
    config = load_config().with_codec("phase")
    phase_codec = codec_class("phase")(SIZE, config.scan.phase)
    data = config.model_dump(mode="json")
    data["scan"]["phase"]["steps"] = radial["frames"] - (phase_codec.frame_count - config.scan.phase.steps)
    config = type(config).model_validate(data)
    with open_rig(config) as the_rig:
        result = run_scan(the_rig)
        assert result.frames_projected == radial["frames"]
        from rig.evaluate.pairs import evaluate_pair

        phase = evaluate_pair(result.pairs[0], the_rig.truth.ground_truth(0, 0), the_rig.truth)  # type: ignore[union-attr]
    assert radial["completeness"] >= 0.90
    assert radial["rms_mm"] <= 2 * phase["rms_mm"]  # the bound
    assert radial["rms_mm"] <= 1.3 * phase["rms_mm"]  # and what it measures: 0.058 against 0.050


def test_ring_crossings_on_pixels_exactly_on_the_ring_are_kept() -> None:
    """8-bit captures often put a pixel exactly on the ring (pattern == inverse); its crossing must
    still be found, once."""
    codec = codec_class("rings")(SIZE)
    patterns = codec.patterns()
    clean = codec.decode(unclipped(patterns), UNCLIPPED_FULL_SCALE).samples
    cu, cv = codec.center
    v, u = np.mgrid[0 : SIZE[1], 0 : SIZE[0]]
    rho = np.hypot(u - cu, v - cv)
    on_ring = np.min(np.abs(rho[..., None] - codec.radii[None, None, :]), axis=2) < 0.2
    edge, inverse = patterns[2].copy(), patterns[3].copy()
    edge[on_ring] = inverse[on_ring] = 128
    samples = codec.decode(unclipped([*patterns[:2], edge, inverse, *patterns[4:]]), UNCLIPPED_FULL_SCALE).samples
    assert clean is not None and samples is not None
    assert on_ring.sum() > 0.1 * len(clean)  # many crossings now run through a zero pixel
    assert len(samples) >= 0.99 * len(clean)
    radius = _radial_distance(samples.camera_xy, samples.center_px)
    assert np.max(np.abs(radius - samples.radius_px)) <= 0.2 + 0.01  # the zeroed pixels are <= 0.2 px off


def test_a_ring_along_the_frames_border_reports_no_edge_the_border_cut() -> None:
    """A camera that sees past the projector's frame (dark around it, optics that blur): the last
    ring runs 2 px outside the top and bottom of the frame and crosses its border at a grazing
    angle. Its ramp cut by the border, the edge found there was 1.2 px off the ring (on a real rig:
    a point centimetres off, where the ring runs along the epipolar direction)."""
    pad = 24
    radii = [40.0 + 24.0 * k for k in range(15)] + [385.4]  # the frame's half-height is 383.5
    codec = codec_class("rings")(SIZE, RingsParams(rings=len(radii), radii_px=radii))
    frames = []
    for pattern in codec.patterns():
        canvas = np.zeros((SIZE[1] + 2 * pad, SIZE[0] + 2 * pad), np.float32)
        canvas[pad:-pad, pad:-pad] = pattern
        frames.append(np.rint(cv2.GaussianBlur(canvas, (0, 0), 1.0)).astype(np.uint8))
    decoded = codec.decode(unclipped(frames), UNCLIPPED_FULL_SCALE)
    samples = decoded.samples
    assert samples is not None
    error = _radial_distance(samples.camera_xy - pad, samples.center_px) - samples.radius_px
    last = samples.ring == len(radii) - 1
    assert last.sum() > 1000  # the ring's sides, well inside the frame, are all there
    assert decoded.counts["rejected_off_frame"] > 0
    assert np.abs(error).max() <= 0.1


def test_ring_radii_and_count_must_agree() -> None:
    with pytest.raises(ValueError, match="radii_px lists 3"):
        RingsParams(rings=32, radii_px=[10.0, 30.0, 60.0])
    codec = codec_class("rings")(SIZE, RingsParams(radii_px=[10.0, 30.0, 60.0]))
    assert len(codec.radii) == 3 and codec.frame_count == 2 + 2 + 2 * 2 + 4 + 4  # + the fine angular code
    classic = codec_class("rings")(SIZE, RingsParams(radii_px=[10.0, 30.0, 60.0], tangential_period_px=None))
    assert classic.frame_count == 2 + 2 + 2 * 2 + 4


def test_a_ring_sample_off_its_neighbours_depth_is_rejected() -> None:
    from rig.geometry import CameraModel
    from rig.pipeline.ring_triangulation import RingPoints, along_ring_support

    camera = CameraModel(640, 480, np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]), np.eye(3), np.zeros(3))
    n = 40
    xy = np.column_stack([np.arange(n, dtype=float) + 100, np.full(n, 200.0)])  # one ring, a sample a pixel
    depth = np.full(n, 600.0)
    depth[20] += 5.0  # a sample on a depth edge: its depth agrees with neither neighbour
    depth[30:] += 0.5  # a gentle step the surface itself has: within the 2 mm limit
    points = np.column_stack([(xy[:, 0] - 320) / 500 * depth, (xy[:, 1] - 240) / 500 * depth, depth])
    rings = RingPoints(
        points=points,
        other_root=np.full_like(points, np.nan),
        origins=np.zeros_like(points),
        directions=points / np.linalg.norm(points, axis=1, keepdims=True),
        camera_xy=xy,
        ring=np.full(n, 7),
        sigma_mm=np.full(n, 0.01),
        cos_beta=np.ones(n),
        kept=np.ones(n, bool),
        contrast=np.ones(n),
    )
    supported = along_ring_support(rings, camera, max_jump_mm=2.0)
    assert not supported[20]
    assert supported[np.r_[1:20, 21 : n - 1]].all()  # every other sample, both sides of the gentle step, stays
    # but for the stretch's two ends: their neighbours lie on one side (an end's pixels straddle a boundary)
    assert not supported[0] and not supported[n - 1]


def test_ring_stretches_that_straddle_a_depth_edge_are_rejected() -> None:
    """On the box a stretch of one ring decodes between the box top and the floor, agreeing with
    itself along the ring; the rings around it do not agree, and it goes."""
    from rig.assembly import open_rig
    from rig.evaluate.pairs import evaluate_on_bench
    from rig.pipeline.scan import run_scan

    config = load_config().with_codec("rings").with_scene({"kind": "box"})
    with open_rig(config) as the_rig:
        filtered = evaluate_on_bench(the_rig, run_scan(the_rig).pairs[0])
    data = config.model_dump(mode="json")
    data["scan"]["max_depth_jump_mm"] = None
    data["scan"]["rings"]["max_edge_step"] = 1.0  # and no ramp test: every sign change is a ring
    with open_rig(config_from_dict(data, "unfiltered")) as the_rig:
        unfiltered = evaluate_on_bench(the_rig, run_scan(the_rig).pairs[0])
    assert unfiltered["max_mm"] > 10 and filtered["max_mm"] < 1.5  # type: ignore[operator]
    assert filtered["rms_mm"] < 0.1 < unfiltered["rms_mm"]  # type: ignore[operator]
    assert filtered["points"] > 0.95 * unfiltered["points"]  # type: ignore[operator]
