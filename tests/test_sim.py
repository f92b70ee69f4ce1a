"""The simulated bench: ground truth, shadows, photometry, noise, timing and faults."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from drivers.errors import DeviceDisconnectedError, DeviceTimeoutError
from drivers.options import CameraSettings, SimCameraOptions, SimFaults, SimProjectorOptions
from drivers.sim import scene as sc
from drivers.sim.bench import SimBench
from drivers.sim.camera import SimCamera
from drivers.sim.projector import SimProjector
from drivers.sim.sensor import NoiseTable, expose
from tests.conftest import make_device

CAMERA = make_device(320, 256, 450.0, (-100.0, 0.0, 600.0), (0.0, 0.0, 30.0))
PROJECTOR = make_device(256, 192, 375.0, (100.0, 0.0, 620.0), (0.0, 0.0, 30.0))


def _bench(objects: list[sc.SceneObject], **kwargs: object) -> SimBench:
    return SimBench(sc.build_scene(objects), [CAMERA], [PROJECTOR], **kwargs)  # type: ignore[arg-type]


def test_plane_ground_truth_is_exact() -> None:
    truth = _bench([sc.plane(2000.0)]).ground_truth(0, 0)
    assert truth.hit.all()
    assert np.max(np.abs(truth.points[..., 2])) < 1e-9
    np.testing.assert_allclose(truth.normals.reshape(-1, 3), np.tile([0, 0, 1.0], (truth.hit.size, 1)))
    _, z = CAMERA.project(truth.points.reshape(-1, 3))
    np.testing.assert_allclose(truth.depth.ravel(), z)


def test_sphere_points_lie_on_the_sphere() -> None:
    truth = _bench([sc.sphere(60.0, (0.0, 0.0, 60.0))]).ground_truth(0, 0)
    radius = np.linalg.norm(truth.points[truth.hit] - [0.0, 0.0, 60.0], axis=1)
    assert truth.hit.sum() > 5000
    assert np.max(np.abs(radius - 60.0)) < 0.01  # the icosphere's facets lie within 0.01 mm


def test_shadows_are_where_the_sphere_blocks_the_projector() -> None:
    center, r = np.array([0.0, 0.0, 60.0]), 60.0
    truth = _bench([sc.plane(600.0), sc.sphere(r, tuple(center))]).ground_truth(0, 0)  # type: ignore[arg-type]
    uv = truth.projector_uv
    in_frame = truth.hit & (uv[..., 0] > 1) & (uv[..., 0] < 254) & (uv[..., 1] > 1) & (uv[..., 1] < 190)
    on_plane = in_frame & (np.abs(truth.points[..., 2]) < 1e-6)
    points = truth.points[on_plane]
    to_proj = PROJECTOR.center - points
    length = np.linalg.norm(to_proj, axis=1)
    d = to_proj / length[:, None]
    # Does the segment from the plane point to the projector pass through the sphere?
    oc = points - center
    b = np.einsum("ij,ij->i", oc, d)
    disc = b * b - (np.einsum("ij,ij->i", oc, oc) - r * r)
    blocked = (disc > 0) & (-b - np.sqrt(np.maximum(disc, 0)) > 0)
    lit = truth.lit[on_plane]
    margin = np.abs(disc) > 40.0  # stay off the shadow's edge, where the facets decide
    assert blocked[margin].sum() > 1000
    np.testing.assert_array_equal(lit[margin], ~blocked[margin])


def test_photometry_follows_lambert_falloff_and_exposure() -> None:
    bench = _bench(
        [sc.plane(2000.0, albedo=0.5)],
        camera_settings=[CameraSettings(exposure_us=6000.0, bit_depth=16)],
        camera_options=[SimCameraOptions(read_noise_e=0.0, blur_px=0.0, full_well_e=1e6)],
        projector_options=[SimProjectorOptions(black_level=0.0, blur_px=0.0)],
        ambient=0.0,
    )
    bench.set_pattern(0, np.full((192, 256), 255, np.uint8))
    image = bench.render(0).astype(float) / 65535
    truth = bench.ground_truth(0, 0)
    to_light = PROJECTOR.center - truth.points
    dist = np.linalg.norm(to_light, axis=2)
    cos_i = to_light[..., 2] / dist
    expected = 0.5 * cos_i * (600.0 / dist) ** 2 * 6000.0 / 12000.0
    uv = truth.projector_uv  # away from the edge of the projected image, which is soft
    inner = truth.lit & (uv[..., 0] > 1) & (uv[..., 0] < 254) & (uv[..., 1] > 1) & (uv[..., 1] < 190)
    np.testing.assert_allclose(image[inner], expected[inner], rtol=0.01)
    bench.set_pattern(0, None)
    assert bench.render(0).max() == 0  # no ambient, no black level: darkness


def test_noise_matches_the_sensor_model() -> None:
    bench = _bench(
        [sc.plane(2000.0)],
        camera_settings=[CameraSettings(bit_depth=16)],
        camera_options=[SimCameraOptions(full_well_e=5000.0, read_noise_e=15.0, blur_px=0.0)],
    )
    bench.set_pattern(0, np.full((192, 256), 128, np.uint8))
    a = bench.render(0).astype(float) / 65535
    b = bench.render(0).astype(float) / 65535
    lit = bench.ground_truth(0, 0).lit
    signal = 0.5 * (a + b)[lit]
    predicted = np.sqrt(2 * (signal * 5000.0 + 15.0**2)) / 5000.0
    measured = (a - b)[lit]
    ratio = np.std(measured) / np.sqrt(np.mean(predicted**2))
    assert 0.95 < ratio < 1.05


@pytest.mark.parametrize(
    ("bit_depth", "gamma", "colour", "gain"), [(8, 1.0, False, 0.8), (12, 2.2, False, 1.5), (16, 1.0, True, 1.5)]
)
def test_the_compiled_sensor_gives_the_counts_of_its_formula(
    bit_depth: int, gamma: float, colour: bool, gain: float
) -> None:
    settings = CameraSettings(exposure_us=8000.0, gain=gain, bit_depth=bit_depth, color=colour)
    options = SimCameraOptions(full_well_e=5000.0, read_noise_e=15.0, blur_px=0.0, gamma=gamma)
    shape = (64, 80, 3) if colour else (64, 80)
    radiance = np.random.default_rng(2).uniform(0.0, 1.6, shape).astype(np.float32)  # dark to past the well
    counts = expose(radiance.copy(), 8000.0, gain, settings, options, NoiseTable(np.random.default_rng(5)))
    # the sensor model step by step, in float32 as numpy evaluates it
    shot = NoiseTable(np.random.default_rng(5)).frame(shape)
    electrons = radiance * np.float32(8000.0 / options.full_scale_exposure_us * 5000.0)
    electrons = electrons + np.sqrt(electrons + np.float32(15.0**2)) * shot
    signal = np.clip(np.minimum(electrons, np.float32(5000.0)) * np.float32(gain / 5000.0), 0.0, 1.0)
    if gamma != 1.0:
        signal = np.power(signal, np.float32(1.0 / gamma))
    expected = np.rint(signal * np.float32(settings.full_scale)).astype(counts.dtype)
    assert counts.dtype == (np.uint8 if bit_depth == 8 else np.uint16) and counts.shape == shape
    assert np.array_equal(counts, expected)
    brightest = round(min(gain, 1.0) ** (1.0 / gamma) * settings.full_scale)  # the full well's, or full scale
    assert counts.min() == 0 and counts.max() == brightest


def test_devices_timestamps_sequences_and_pattern_checks() -> None:
    bench = _bench([sc.plane(1000.0)])
    projector, camera = SimProjector("p", bench, 0), SimCamera("c", bench, 0)
    projector.open()
    camera.open()
    projector.show(np.full((192, 256), 255, np.uint8))
    frames = [camera.capture() for _ in range(3)]
    assert [f.sequence for f in frames] == [1, 2, 3]
    assert frames[0].timestamp_s < frames[1].timestamp_s < frames[2].timestamp_s
    with pytest.raises(ValueError, match="pattern must be uint8"):
        projector.show(np.zeros((10, 10), np.uint8))
    with pytest.raises(ValueError):
        camera.capture(timeout_s=0)
    projector.close()
    assert projector.is_dark


def test_camera_faults_fail_cleanly_and_finitely() -> None:
    bench = _bench([sc.plane(1000.0)])
    camera = SimCamera("c", bench, 0, SimFaults(disconnect_after_frames=1))
    camera.open()
    camera.capture()
    with pytest.raises(DeviceDisconnectedError):
        camera.capture()
    stalled = SimCamera("s", bench, 0, SimFaults(stall_after_frames=0))
    stalled.open()
    start = time.monotonic()
    with pytest.raises(DeviceTimeoutError):
        stalled.capture(timeout_s=0.2)
    assert 0.15 < time.monotonic() - start < 2.0


def test_mesh_file_is_scaled_and_placed_on_its_base(tmp_path: Path) -> None:
    path = tmp_path / "capsule.obj"
    trimesh.creation.capsule(height=2.0, radius=1.0).export(path)
    obj = sc.mesh_file(path, position_mm=(10.0, -5.0, 0.0), fit_size_mm=80.0)
    extents = obj.vertices.max(axis=0) - obj.vertices.min(axis=0)
    assert max(extents) == pytest.approx(80.0)
    assert obj.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    center = 0.5 * (obj.vertices.max(axis=0) + obj.vertices.min(axis=0))
    np.testing.assert_allclose(center[:2], [10.0, -5.0], atol=1e-9)
    with pytest.raises(FileNotFoundError):
        sc.mesh_file(tmp_path / "absent.ply")
    (tmp_path / "junk.ply").write_text("not a mesh")
    with pytest.raises(ValueError):
        sc.mesh_file(tmp_path / "junk.ply")


def test_a_frame_exposed_across_a_pattern_change_sees_both() -> None:
    bench = _bench(
        [sc.plane(2000.0)],
        camera_settings=[CameraSettings(exposure_us=10000.0, bit_depth=16)],
        camera_options=[SimCameraOptions(read_noise_e=0.0, full_well_e=1e7, blur_px=0.0)],
        projector_options=[SimProjectorOptions(latency_s=0.05, black_level=0.0)],
        ambient=0.0,
    )
    bench.set_pattern(0, np.full((192, 256), 255, np.uint8))  # lit from bench time 0.05
    before = bench.render(0, time_s=0.03).mean()  # exposed 0.030-0.040: dark
    across = bench.render(0, time_s=0.045).mean()  # 0.045-0.055: half dark, half lit
    after = bench.render(0, time_s=0.06).mean()  # 0.060-0.070: lit
    assert before == 0 and after > 0
    assert across == pytest.approx(after / 2, rel=0.01)


def test_a_bench_built_again_reuses_the_geometry_and_a_moved_camera_or_scene_does_not() -> None:
    """The ray casts are kept for the process by content (drivers.sim.memo): an equal scene and pose
    built apart share them, read-only; a camera moved by a millimetre or another scene does not."""
    from drivers.sim import memo

    memo.forget()
    first = _bench([sc.plane(300.0, 0.5)]).ground_truth(0, 0)
    again = _bench([sc.plane(300.0, 0.5)]).ground_truth(0, 0)
    assert again.points is not first.points and np.shares_memory(again.points, first.points)
    with pytest.raises(ValueError, match="read-only"):
        again.points[0, 0, 0] = 1.0
    moved = make_device(320, 256, 450.0, (-99.0, 0.0, 600.0), (0.0, 0.0, 30.0))
    elsewhere = SimBench(sc.build_scene([sc.plane(300.0, 0.5)]), [moved], [PROJECTOR]).ground_truth(0, 0)  # type: ignore[list-item]
    assert not np.shares_memory(elsewhere.points, first.points)
    other = _bench([sc.plane(300.0, 0.4)]).ground_truth(0, 0)
    assert not np.shares_memory(other.points, first.points) and np.array_equal(
        other.points, first.points, equal_nan=True
    )
    dimmer = _bench([sc.plane(300.0, 0.5)], projector_options=[SimProjectorOptions(brightness=0.5)])
    lit = first.lit & (first.white_irradiance > 0.1)  # a projector's brightness is in its lighting's key
    np.testing.assert_allclose(
        dimmer.ground_truth(0, 0).white_irradiance[lit] - 0.02, 0.5 * (first.white_irradiance[lit] - 0.02), rtol=1e-5
    )


def test_a_printed_plane_paints_its_own_pixels_alone_each_with_its_footprints_mean() -> None:
    """paint_planar_textures over part of a view: a pixel of the plane takes the mean of the print
    over its footprint (for a print linear in position, the print at the pixel's centre), at the
    plane's edge too; a pixel of another object or of nothing keeps its albedo."""
    from drivers.sim.texture import PlanarTexture, paint_planar_textures

    height, width = 40, 60
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float64)
    points = np.stack([cols * 0.5, rows * 0.5, np.zeros_like(cols)], axis=-1).reshape(-1, 3)  # 0.5 mm a pixel
    faces = np.full((height, width), -1)
    faces[5:30, 10:45] = 0  # the plane: object 0's face
    faces[30:35, 10:45] = 1  # another object below it
    ramp = np.tile(np.linspace(0.2, 0.8, 200, dtype=np.float32), (120, 1))  # linear along the print's x
    texture = PlanarTexture(ramp, 0.25, np.zeros(3), np.eye(3))
    albedo = np.full((height, width, 3), 0.5, np.float32)
    paint_planar_textures(albedo, points, faces.ravel(), [texture, None], np.array([0, 1]))
    plane = faces == 0
    assert (albedo[~plane] == 0.5).all()
    col_in_print = cols[plane] * 0.5 / 0.25 - 0.5  # the pixel centre's print column
    expected = np.interp(col_in_print, np.arange(200), ramp[0])
    assert np.abs(albedo[plane][:, 0] - expected).max() < 1e-5
    assert np.array_equal(albedo[plane][:, 0], albedo[plane][:, 2])


@pytest.mark.parametrize("shape", [(7, 5), (480, 640)])
def test_opencvs_blur_in_place_and_remap_into_a_buffer_are_its_new_images(shape: tuple[int, int]) -> None:
    """The simulator blurs a frame's radiance in place and remaps the light into a scratch image
    (drivers.sim.sensor, drivers.sim.bench): OpenCV must give the values it gives into new images."""
    import cv2

    rng = np.random.default_rng(shape[0])
    radiance = rng.random(shape, dtype=np.float32)
    fresh = cv2.GaussianBlur(radiance, (0, 0), 1.5, borderType=cv2.BORDER_REPLICATE)
    cv2.GaussianBlur(radiance, (0, 0), 1.5, dst=radiance, borderType=cv2.BORDER_REPLICATE)
    assert np.array_equal(radiance, fresh) and not np.array_equal(fresh, rng.random(shape, dtype=np.float32))
    light = rng.random((shape[0] + 3, shape[1] + 5), dtype=np.float32)
    map_x = rng.uniform(-2, shape[1] + 6, shape).astype(np.float32)
    map_y = rng.uniform(-2, shape[0] + 4, shape).astype(np.float32)
    into = np.empty(shape, np.float32)
    sampled = cv2.remap(light, map_x, map_y, cv2.INTER_LINEAR, dst=into, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    assert sampled is into
    assert np.array_equal(
        into, cv2.remap(light, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    )
