"""The ring surface's compiled loops (rig.kernels.triangles, rig.kernels.ring_surface) against the
formulas they implement, written here as plain numpy, on devices the default bench does not have:
a distorted and an orthographic projector, an orthographic camera (a ray per pixel)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import face_normals, face_weights, make_device

from rig.geometry import CameraModel
from rig.kernels.triangles import GAP, KEPT, ONE_RING, RING_SKIPPED
from rig.pipeline.raster import FaceTerms, points_on_faces
from rig.pipeline.ring_faces import _tested
from rig.pipeline.surface import RingBands, SurfaceSettings, band_agreement

RNG = np.random.default_rng(7)


def _projectors() -> dict[str, CameraModel]:
    return {
        "pinhole": make_device(320, 240, 400.0, (80.0, 0.0, 600.0)),
        "distorted": make_device(320, 240, 400.0, (80.0, 0.0, 600.0), dist=(0.08, -0.05, 0.001, -0.002, 0.01)),
        "orthographic": make_device(320, 240, 0.8, (80.0, 0.0, 600.0), projection="orthographic"),
    }


def _bands(camera: CameraModel) -> RingBands:
    """Random reads: a third of the pixels unread in annulus, a third unread in angle."""
    shape = (camera.height, camera.width)
    annulus = RNG.integers(-1, 9, size=shape).astype(np.int16)
    angle = RNG.uniform(-np.pi, np.pi, size=shape).astype(np.float32)
    angle[RNG.random(shape) < 0.3] = np.nan
    return RingBands(annulus, angle, np.linspace(10.0, 120.0, 8), (160.0, 120.0))


def _agreement(
    found: np.ndarray, pixel: np.ndarray, projector: CameraModel, bands: RingBands
) -> tuple[np.ndarray, np.ndarray]:
    """band_agreement's rule: in the annulus read (padded by band_margin_px), within band_angle_rad of
    the angle read (not within 8 px of the centre), in front of the projector; and which points lie
    within 1e-6 rad of the angle's limit (the compiled loop's float32 atan2 may place them either side)."""
    settings = SurfaceSettings()
    u, v, z = projector.project_columns(found)
    du, dv = u - bands.center_px[0], v - bands.center_px[1]
    rho = np.hypot(du, dv)
    annulus = bands.annulus.ravel()[pixel]
    radii = np.concatenate([[-np.inf], bands.radii_px, [np.inf]])
    a = np.clip(annulus, 0, len(bands.radii_px)).astype(np.intp)
    inside = (rho >= radii[a] - settings.band_margin_px) & (rho <= radii[a + 1] + settings.band_margin_px)
    angle = bands.angle.ravel()[pixel]
    turned = np.abs(np.remainder(np.arctan2(dv, du) - angle + np.pi, 2 * np.pi) - np.pi)
    aligned = ~np.isfinite(angle) | (turned <= settings.band_angle_rad) | (rho < 8.0)
    return (z > 0) & (inside | (annulus < 0)) & aligned, np.abs(turned - settings.band_angle_rad) < 1e-6


@pytest.mark.parametrize("kind", ["pinhole", "distorted", "orthographic"])
def test_band_agreement_follows_its_rule_on_every_kind_of_projector(kind: str) -> None:
    projector = _projectors()[kind]
    camera = make_device(160, 120, 200.0, (0.0, 0.0, 600.0))
    bands = _bands(camera)
    # points the projector sees all over its rings (and a few behind it, and NaN)
    target = np.column_stack([RNG.uniform(-90, 90, 5000), RNG.uniform(-70, 70, 5000), RNG.uniform(-40, 40, 5000)])
    target[:20] = projector.center + 50.0 * (projector.center - target[:20]) / 600.0  # behind
    target[20:30] = np.nan
    pixel = RNG.integers(0, camera.width * camera.height, size=len(target))
    agree = band_agreement(target, pixel, projector, bands, SurfaceSettings())
    expected, borderline = _agreement(target, pixel, projector, bands)
    assert 0.05 < expected.mean() < 0.95  # both verdicts are exercised
    assert borderline.sum() <= 2
    np.testing.assert_array_equal(agree[~borderline], expected[~borderline])


def _on_faces(terms: FaceTerms, pixel: np.ndarray, owner: np.ndarray, camera: CameraModel) -> np.ndarray:
    """Each pixel's point (N, 3), a row per pixel."""
    found = np.empty((len(pixel), 3))
    rows, finite = np.arange(len(pixel)), np.empty(len(pixel), bool)
    points_on_faces(terms, pixel, owner, camera.pixel_rays, camera.width, (found, rows, finite))
    return found


@pytest.mark.parametrize("projection", ["pinhole", "orthographic"])
def test_points_on_faces_lie_on_their_planes_and_rays(projection: str) -> None:
    """Linear: where each pixel's ray meets its face's plane; quadratic: within a quarter of the
    face's longest edge of that point, on the same ray."""
    f = 200.0 if projection == "pinhole" else 0.5
    camera = make_device(160, 120, f, (0.0, 0.0, 600.0), projection=projection)
    xy = np.array([[20.0, 15.0], [140.0, 20.0], [30.0, 110.0], [150.0, 100.0]])
    depth = np.array([0.0, 10.0, -15.0, 5.0])
    origins, directions = camera.rays(xy)
    points = np.asarray(origins) + (600.0 + depth)[:, None] * np.asarray(directions)
    tri = np.array([[0, 1, 2], [1, 3, 2]])
    normals = np.array([[0.1, -0.2, -1.0], [-0.2, 0.1, -1.0], [0.3, 0.2, -1.0], [0.0, -0.3, -1.0]])  # a bent surface
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    pixel = np.array([40 * 160 + 50, 60 * 160 + 80, 90 * 160 + 120, 70 * 160 + 130])
    owner = np.array([0, 0, 1, 1])
    origin = camera.center if projection == "pinhole" else None
    linear = _on_faces(FaceTerms.of(points, xy, tri, None, origin), pixel, owner, camera)
    o, d = (np.asarray(r)[pixel] for r in camera.pixel_rays)
    corner = points[tri[owner]]
    plane = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
    t = np.einsum("ij,ij->i", plane, corner[:, 0] - o) / np.einsum("ij,ij->i", plane, d)
    np.testing.assert_allclose(linear, o + t[:, None] * d, atol=1e-9)
    quadratic = _on_faces(FaceTerms.of(points, xy, tri, normals[tri], origin), pixel, owner, camera)
    off_ray = np.linalg.norm(np.cross(quadratic - o, d), axis=1)
    assert off_ray.max() < 1e-9
    longest = np.linalg.norm(corner - corner[:, [1, 2, 0]], axis=2).max(axis=1)
    moved = np.linalg.norm(quadratic - linear, axis=1)
    assert (moved <= 0.25 * longest + 1e-9).all() and moved.max() > 1e-3  # the tangent planes bend it


@pytest.mark.parametrize("kind", ["pinhole", "orthographic"])
def test_triangle_tests_give_numpys_normals_weights_and_foreshortening(kind: str) -> None:
    camera = make_device(320, 240, 400.0, (0.0, 0.0, 600.0))
    projector = _projectors()[kind]
    count = 60
    xy = np.column_stack([RNG.uniform(10, 310, count), RNG.uniform(10, 230, count)])
    origins, directions = camera.rays(xy)
    directions = np.asarray(directions)
    points = np.asarray(origins) + RNG.uniform(560, 640, count)[:, None] * directions
    ring = RNG.integers(0, 4, count)
    tri = RNG.integers(0, count, size=(200, 3))
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]
    verdict, face, weight, slant, foreshortened = _tested(points, xy, ring, camera, projector, directions, tri, 60.0)
    np.testing.assert_allclose(face, face_normals(points, tri, directions), atol=1e-12)
    nxt = [1, 2, 0]
    edge_mm = np.linalg.norm(points[tri][:, nxt] - points[tri], axis=2)
    np.testing.assert_allclose(weight, face_weights(edge_mm), rtol=1e-12)
    np.testing.assert_allclose(slant, np.abs(np.einsum("ij,ij->i", face, directions[tri[:, 0]])), atol=1e-12)
    product = np.ones_like(edge_mm)
    for device in (camera, projector):
        image = device.project(points)[0][tri]
        pixels = np.linalg.norm(image[:, nxt] - image, axis=2)
        ortho = device.projection == "orthographic"
        depth = np.ones(tri.shape) if ortho else device.to_device(points)[:, 2][tri]
        mm = 0.5 * (depth + depth[:, nxt]) / device.K[0, 0]
        product *= np.minimum(1.0, pixels * mm / np.maximum(edge_mm, 1e-12))
    np.testing.assert_allclose(foreshortened, product.min(axis=1), rtol=1e-12)
    r = ring[tri]
    span = r.max(axis=1) - r.min(axis=1)
    image_edge = np.linalg.norm(xy[tri][:, nxt] - xy[tri], axis=2)
    gap = ((r == r[:, nxt]) & (image_edge > 60.0)).any(axis=1)
    expected = np.where(span > 1, RING_SKIPPED, np.where(span == 0, ONE_RING, np.where(gap, GAP, KEPT)))
    assert len(set(expected.tolist())) == 4  # every verdict is exercised
    np.testing.assert_array_equal(verdict, expected)


def test_a_face_mostly_off_its_bands_loses_all_its_pixels() -> None:
    """settled_pixels against its rule in numpy: a pixel keeps its point if found, in its own band,
    and in a face with no more than the allowed share of its pixels off their bands; a kept pixel is
    valid with its face, the others' points NaN, and every other pixel of the grid left alone."""
    from rig.pipeline.raster import settled_pixels

    faces, pixels, image = 200, 20_000, 30_000
    owner = RNG.integers(0, faces, pixels)
    pixel = np.sort(RNG.choice(image, pixels, replace=False))  # listed in row-major order
    off_share = RNG.uniform(0, 0.6, faces)  # each face's own share of pixels off their bands
    agree = RNG.random(pixels) >= off_share[owner]
    ok = RNG.random(pixels) > 0.1
    grid = RNG.normal(size=(image, 3))
    before = grid.copy()
    area = np.bincount(owner, minlength=faces)
    bridging = np.bincount(owner, ~agree, minlength=faces) > 0.25 * area
    expected_agree = agree & ~bridging[owner]
    expected_dropped = int((ok & ~expected_agree).sum())
    expected_ok = ok & expected_agree
    assert 0 < bridging.sum() < faces  # some faces bridge, some do not
    valid, triangle, dropped = settled_pixels((pixel, owner), (ok, agree), faces, 0.25, grid)
    assert dropped == expected_dropped
    assert np.array_equal(agree, expected_agree) and np.array_equal(ok, expected_ok)
    expected_triangle = np.full(image, -1)
    expected_triangle[pixel[expected_ok]] = owner[expected_ok]
    np.testing.assert_array_equal(triangle, expected_triangle)
    np.testing.assert_array_equal(valid, expected_triangle >= 0)
    cleared = np.zeros(image, bool)
    cleared[pixel[~expected_ok]] = True
    assert np.isnan(grid[cleared]).all() and np.array_equal(grid[~cleared], before[~cleared])


def test_without_bands_every_found_pixel_keeps_its_point() -> None:
    """settled_pixels with no band test (faces = 0, a rig without ring bands): found pixels are
    kept whatever `agree` says, and none is counted as turned away; no pixels make empty images."""
    from rig.pipeline.raster import settled_pixels

    pixel, owner = np.array([3, 5, 8], np.int32), np.array([0, 1, 1], np.int32)
    ok, agree = np.array([True, False, True]), np.array([False, False, True])
    grid = np.ones((10, 3))
    valid, triangle, dropped = settled_pixels((pixel, owner), (ok, agree), 0, 0.25, grid)
    assert dropped == 0 and ok.tolist() == [True, False, True] and agree.tolist() == [False, False, True]
    assert np.flatnonzero(valid).tolist() == [3, 8] and triangle[[3, 5, 8]].tolist() == [0, -1, 1]
    assert np.isnan(grid[5]).all() and np.isfinite(np.delete(grid, 5, axis=0)).all()
    nothing = (np.zeros(0, np.int32), np.zeros(0, np.int32))
    valid, triangle, dropped = settled_pixels(nothing, (np.zeros(0, bool),) * 2, 4, 0.25, np.ones((6, 3)))
    assert dropped == 0 and not valid.any() and (triangle == -1).all()


def test_rasterised_strips_make_the_image_one_pass_makes() -> None:
    """Threads rasterise strips of rows, each taking every triangle in order: the later triangle
    still wins a shared pixel, so the image is the one a single pass over all rows draws."""
    from rig.kernels.triangles import rasterize

    xy = RNG.uniform(-10.0, 90.0, size=(60, 2))  # some corners off the 80 x 64 image
    tri = RNG.integers(0, 60, size=(200, 3))  # overlapping triangles: shared pixels to contend for
    whole = np.empty((64, 80), np.int32)
    rasterize(xy, tri, whole, (0, 64))
    assert (whole >= 0).sum() > 1000 and len(np.unique(whole)) > 20  # many triangles, many pixels
    strips = np.full((64, 80), 7, np.int32)  # each strip clears its own rows
    for top, bottom in ((0, 5), (5, 6), (6, 40), (40, 64)):
        rasterize(xy, tri, strips, (top, bottom))
    np.testing.assert_array_equal(strips, whole)
