"""The kept triangles of a ring scan's samples (rig.pipeline.surface, whose module docstring says
which are kept): the tests every image triangle meets, and the samples' normals from the kept ones,
in rounds that drop the triangles bridging a step."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.geometry import CameraModel
from rig.kernels import kept_rows
from rig.lazy import lazy_module
from rig.pipeline.flanks import grown_flanks
from rig.pipeline.normals import ring_pairs, smoothed_normals, vertex_normals
from rig.pipeline.surface_settings import SurfaceSettings
from rig.pipeline.triangulation import delaunay
from rig.workers import POOL_WAIT_S, batches, pool

normal_kernels = lazy_module("rig.kernels.normals")  # numba compiles on first use
triangle_kernels = lazy_module("rig.kernels.triangles")

_BRIDGE_ROUNDS = 4  # rounds of dropping triangles bent off their corners (ring_triangles)


@dataclass(frozen=True, eq=False)
class RingTriangles:
    """The kept triangles of a pair's ring samples (ring_triangles)."""

    tri: np.ndarray  # (F, 3) sample indices
    face: np.ndarray  # (F, 3) unit normals, toward the camera
    weight: np.ndarray  # (F,) 1 / longest edge (rig.pipeline.normals.vertex_normals)
    normals: np.ndarray  # (M, 3) the samples' unit normals, toward the camera
    counts: dict[str, int]  # how many triangles each test dropped
    directions: np.ndarray  # (M, 3) the samples' camera rays
    pairs: np.ndarray  # (P, 2) samples of one ring whose normals are averaged (ring_pairs)
    flank: np.ndarray  # (F,) bool: steep to both devices, kept as a flank (rig.pipeline.flanks)

    def subset(self, keep: np.ndarray) -> RingTriangles:
        """These triangles but only those `keep` marks, the samples' normals from them alone (a
        dropped triangle bridged a step: its tilt is no part of either side's normal)."""
        tri, face, weight = self.tri[keep], self.face[keep], self.weight[keep]
        return RingTriangles(tri, face, weight, _normals(tri, face, weight, self.directions, self.pairs), self.counts,
                             self.directions, self.pairs, self.flank[keep])  # fmt: skip


def _normals(
    tri: np.ndarray, face: np.ndarray, weight: np.ndarray, directions: np.ndarray, pairs: np.ndarray
) -> np.ndarray:
    normals = vertex_normals(tri, face, weight, directions)
    in_triangle = np.bincount(tri.ravel(), minlength=len(directions)) > 0  # the others' normals are a guess
    return smoothed_normals(normals, pairs, in_triangle)


def ring_triangles(
    points: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    settings: SurfaceSettings,
    tri: np.ndarray | None = None,
    directions: np.ndarray | None = None,
) -> RingTriangles:
    """The kept triangles of the samples' image Delaunay triangulation `tri` (see the module
    docstring); `directions`: the samples' camera rays, where known (the triangulation's)."""
    directions = np.asarray(camera.rays(xy)[1]) if directions is None else directions
    # the samples' neighbours along their rings need no triangles: found beside the triangle tests
    neighbours = pool().submit(ring_pairs, points, xy, ring, settings.normal_smoothing_px)
    tri = delaunay(xy) if tri is None else tri
    tested = _tested(points, xy, ring, camera, projector, directions, tri, settings.max_gap_px)
    verdict, face, weight, slant, foreshortened = tested
    counts = {"triangles": len(tri)}
    verdicts = {"ring_skipped": triangle_kernels.RING_SKIPPED, "gap": triangle_kernels.GAP}
    for name, code in (*verdicts.items(), ("one_ring", triangle_kernels.ONE_RING)):
        counts[f"dropped_{name}"] = int((verdict == code).sum())
    keep = verdict == triangle_kernels.KEPT
    tri, face, weight, slant, foreshortened = kept_rows(keep, tri, face, weight, slant, foreshortened)
    edge_on = slant < np.cos(np.radians(settings.max_slant_deg))
    steep = ~edge_on & (foreshortened < settings.min_foreshortening)
    edge_on |= steep
    held = kept_rows(steep, tri, face, weight)  # a flank or a bridge: told apart once the rest is known
    tri, face, weight = kept_rows(~edge_on, tri, face, weight)
    normals = vertex_normals(tri, face, weight, directions)
    bent = normal_kernels.bent_from_corners(normals, tri, face, np.cos(np.radians(settings.max_bend_deg)))
    tri, face, weight = kept_rows(~bent, tri, face, weight)
    pairs = neighbours.result(timeout=POOL_WAIT_S)
    # corners' normals as the interpolant takes them (smoothed along the rings), without the
    # triangles dropped so far: a triangle that bridges a step stands out once its neighbours that
    # bridge it too are gone, so a few rounds
    dropped = int(edge_on.sum() + bent.sum())
    normals = _normals(tri, face, weight, directions, pairs)
    for _ in range(_BRIDGE_ROUNDS):
        again = _off_its_corners(normals, tri, face, settings.max_bend_excess_deg)
        if not again.any():
            break
        (tri, face, weight), dropped = kept_rows(~again, tri, face, weight), dropped + int(again.sum())
        normals = _normals(tri, face, weight, directions, pairs)
    flank = grown_flanks((tri, face, weight), held, directions, settings.max_flank_turn_deg)
    if flank.any():
        tri, face, weight = (np.concatenate([k, h[flank]]) for k, h in zip((tri, face, weight), held, strict=True))
        normals = _normals(tri, face, weight, directions, pairs)
    counts["kept_flank"] = int(flank.sum())
    counts["dropped_depth_edge"] = dropped - counts["kept_flank"]
    steep = np.concatenate([np.zeros(len(tri) - counts["kept_flank"], dtype=bool), np.ones(counts["kept_flank"], bool)])
    counts["faces"] = len(tri)
    return RingTriangles(tri, face, weight, normals, counts, directions, pairs, steep)


def _tested(
    points: np.ndarray,
    xy: np.ndarray,
    ring: np.ndarray,
    camera: CameraModel,
    projector: CameraModel,
    directions: np.ndarray,
    tri: np.ndarray,
    max_gap_px: float,
) -> tuple[np.ndarray, ...]:
    """Every triangle's verdict on its rings, unit normal toward the camera, weight (1 / its longest
    edge: rig.pipeline.normals.vertex_normals), slant to the camera and foreshortening to both
    devices (rig.pipeline.flanks): a compiled pass over spans of the triangles on the pool
    (rig.kernels.triangles.triangle_tests), from the samples' depths and projector pixels."""
    depths = np.ones((len(points), 2))
    for k, device in enumerate((camera, projector)):
        if device.projection != "orthographic":
            depths[:, k] = device.to_device(points)[:, 2]
    focal = (float(camera.K[0, 0]), float(projector.K[0, 0]))
    count = len(tri)
    out = (np.empty(count, np.int8), np.empty((count, 3)), np.empty(count), np.empty(count), np.empty(count))
    arrays = (
        np.ascontiguousarray(tri, np.int64), ring.astype(np.int64), np.ascontiguousarray(xy, np.float64),
        projector.project(points)[0], np.ascontiguousarray(points, np.float64), directions, depths,
        (float(max_gap_px), *focal),
    )  # fmt: skip
    list(pool().map(lambda span: triangle_kernels.triangle_tests(*arrays, *out, *span), batches(count)))
    return out


def _off_its_corners(normals: np.ndarray, tri: np.ndarray, face: np.ndarray, max_excess_deg: float) -> np.ndarray:
    """Triangles `tri` tilted away from a corner's normal (`normals`) by `max_excess_deg` more than
    the corners' normals differ among themselves: the corners agree on a surface the triangle does not
    lie on, as when it joins the rings of two treads of a step. On a smooth surface a triangle's
    normal lies among its corners' normals. A compiled pass on the pool (rig.kernels.normals.off_corners)."""
    tri, off = np.ascontiguousarray(tri, np.int64), np.empty(len(face), np.bool_)
    arrays = (normals, tri, face, max_excess_deg, off)
    list(pool().map(lambda span: normal_kernels.off_corners(*arrays, *span), batches(len(face))))
    return off
