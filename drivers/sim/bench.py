"""The physical model behind the simulated devices.

Deferred rendering: rays are cast once per camera (the geometry pass) and once per
(camera, projector) pair (shadows and the projector mapping); every frame is then a per-pixel
gather: pattern lookup through the projector's gamma and defocus, Lambertian shading with distance
fall-off and ambient light, then the camera: optical blur, shot and read noise, gain, response
curve and quantisation.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np

from drivers.options import CameraSettings, SimCameraOptions, SimProjectorOptions
from drivers.sim import memo
from drivers.sim.materials import shininess, specular_gain
from drivers.sim.scene import Scene
from drivers.sim.sensor import NoiseTable, expose
from drivers.sim.texture import paint_planar_textures
from drivers.sim.truth import PixelTruth, SeenSurface

_SHADOW_EPS_MM = 0.02
_LIGHTING_CHUNK = 1 << 18
REFERENCE_DISTANCE_MM = 600.0  # where a projector's `brightness` is its irradiance at normal incidence


class ViewModel(Protocol):
    """The geometry the simulator needs of a camera or projector (see rig.geometry.CameraModel)."""

    width: int
    height: int
    projection: str

    @property
    def center(self) -> np.ndarray: ...

    @property
    def axis(self) -> np.ndarray: ...

    @property
    def pixel_rays(self) -> tuple[np.ndarray, np.ndarray]: ...

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass(frozen=True, eq=False)
class _CameraView:
    hit: np.ndarray  # (N,) over pixels, row-major
    points: np.ndarray  # (N, 3)
    normals: np.ndarray
    albedo: np.ndarray  # (H, W, 3) float32, BGR
    albedo_mono: np.ndarray  # (H, W) float32 luminance
    depth: np.ndarray  # (N,)
    seen: SeenSurface
    specular: np.ndarray | None = None  # (N,) the specular lobe's strength, None for a matte scene
    exponent: np.ndarray | None = None  # (N,) its Blinn-Phong exponent (drivers.sim.materials)


@dataclass(frozen=True, eq=False)
class _Illumination:
    map_x: np.ndarray  # (H, W) float32 projector u per camera pixel, -1e4 where unlit
    map_y: np.ndarray
    irradiance_gain: np.ndarray  # (H, W) float32: cos(incidence) * fall-off * brightness * lit
    uv: np.ndarray  # (N, 2) float64
    lit: np.ndarray  # (N,)
    specular_gain: np.ndarray | None = None  # (H, W) float32: the lobe's radiance per emitted light


class SimBench:
    """A scene seen by cameras and lit by projectors, all with known geometry."""

    def __init__(
        self,
        scene: Scene,
        cameras: list[ViewModel],
        projectors: list[ViewModel],
        camera_settings: list[CameraSettings] | None = None,
        camera_options: list[SimCameraOptions] | None = None,
        projector_options: list[SimProjectorOptions] | None = None,
        ambient: float = 0.02,
        seed: int = 0,
    ) -> None:
        self.scene = scene
        self.cameras = list(cameras)
        self.projectors = list(projectors)
        self.camera_settings = camera_settings or [CameraSettings() for _ in cameras]
        self.camera_options = camera_options or [SimCameraOptions() for _ in cameras]
        self.projector_options = projector_options or [SimProjectorOptions() for _ in projectors]
        self.ambient = ambient
        self._noise = NoiseTable(np.random.default_rng(seed))
        self._scene_key, self._caster = memo.scene_caster(scene)
        self._views: dict[int, _CameraView] = {}
        self._illumination: dict[tuple[int, int], _Illumination] = {}
        self._truths: dict[tuple[int, int], PixelTruth] = {}
        # what each projector emits from when: (bench time, light or None for dark), oldest first
        self._history: list[list[tuple[float, np.ndarray | None]]] = [[(0.0, None)] for _ in projectors]
        self._recent_light: list[list[tuple[np.ndarray, np.ndarray]]] = [[] for _ in projectors]
        self.clock_s = 0.0
        self.trigger_times: list[float] = []  # pulses on the projectors' trigger outputs, bench time

    # --- projector state -------------------------------------------------------------------
    def set_pattern(self, projector: int, pattern: np.ndarray | None) -> None:
        """Make projector `projector` emit `pattern` (uint8, its resolution), or black for None,
        from its latency after now on the bench clock, instead of anything scheduled from then on
        (the rest of a playing sequence stops)."""
        params = self.projector_options[projector]
        start = self.clock_s + params.latency_s
        history = self._history[projector]
        history[:] = [entry for entry in history if entry[0] < start]  # it replaces what a sequence had scheduled
        history.append((start, pattern))
        del history[:-8]

    def play(self, projector: int, patterns: list[np.ndarray], period_s: float) -> float:
        """Play `patterns` back to back, one per `period_s`, from now plus the projector's latency,
        then dark; each pattern's start pulses the trigger output. Returns when the last ends."""
        start = self.clock_s + self.projector_options[projector].latency_s
        history = self._history[projector]
        for k, pattern in enumerate(patterns):
            history.append((start + k * period_s, pattern))
            self.trigger_times.append(start + k * period_s)
        end = start + len(patterns) * period_s
        history.append((end, None))
        del history[: -(len(patterns) + 8)]
        return end

    def emitted_at(self, projector: int, time_s: float) -> np.ndarray | None:
        """The light a projector gives at bench time `time_s` (None: dark)."""
        current = None
        for start, pattern in self._history[projector]:
            if start <= time_s:
                current = pattern
        return None if current is None else self._light(projector, current)

    def _light(self, projector: int, pattern: np.ndarray) -> np.ndarray:
        """A pattern's emitted light, worked out when a frame first sees it and kept for the next
        frames: the history holds the projector's uint8 images, not their float32 light (a scan's
        patterns in light were 3 MB each on the default bench)."""
        recent = self._recent_light[projector]
        for shown, light in recent:
            if shown is pattern:
                return light
        light = self._emission(projector, pattern)
        recent.insert(0, (pattern, light))
        del recent[2:]  # a frame exposed across a pattern change sees two
        return light

    def advance(self, seconds: float) -> None:
        """Let bench time pass (the simulated equivalent of waiting)."""
        self.clock_s += max(0.0, seconds)

    def _emission(self, projector: int, pattern: np.ndarray) -> np.ndarray:
        params = self.projector_options[projector]
        lut = (np.arange(256, dtype=np.float64) / 255.0) ** params.gamma
        lut = params.black_level + (1.0 - params.black_level) * lut
        emitted = cv2.LUT(pattern, lut.astype(np.float32))  # numpy's lut[pattern] took 2.4 ms a frame
        if params.blur_px > 0:
            emitted = cv2.GaussianBlur(emitted, (0, 0), params.blur_px, borderType=cv2.BORDER_REPLICATE)
        return emitted

    # --- geometry, computed once per pose --------------------------------------------------
    def _view(self, camera: int) -> _CameraView:
        if camera not in self._views:
            key = memo.keyed(self._scene_key, memo.device_key(self.cameras[camera]))
            self._views[camera] = memo.remembered("view", key, lambda: self._cast_view(camera))
        return self._views[camera]

    def _cast_view(self, camera: int) -> _CameraView:
        """What camera `camera` sees: the first hit of each pixel's ray, its normal, albedo and depth."""
        model = self.cameras[camera]
        origins, directions = model.pixel_rays
        distance, faces = self._caster.first_hit(origins, directions)
        hit = faces >= 0
        points = np.full(origins.shape, np.nan)
        points[hit] = origins[hit] + distance[hit, None] * directions[hit]
        normals = np.zeros_like(points)
        n = self._caster.face_normals(faces[hit])
        flip = np.einsum("ij,ij->i", n, directions[hit]) > 0
        n[flip] *= -1
        normals[hit] = n
        albedo = np.zeros((len(hit), 3), dtype=np.float32)
        albedo[hit] = self.scene.face_albedo[faces[hit]][:, ::-1]
        if self.scene.texture is not None:
            albedo[hit] = self.scene.texture.colour_at(points[hit])[:, ::-1]
        albedo = albedo.reshape(model.height, model.width, 3)
        textures = [o.texture for o in self.scene.objects]
        paint_planar_textures(albedo, points, faces, textures, self.scene.face_object)
        mono = albedo @ np.array([0.114, 0.587, 0.299], dtype=np.float32)  # BGR luminance weights
        depth = np.zeros(len(hit))
        depth[hit] = points[hit] @ model.axis - model.axis @ model.center  # device-frame z
        view = _CameraView(hit, points, normals, albedo, mono, depth, SeenSurface(points, hit))
        if self.scene.glossy:
            strength, roughness = self.scene.face_material()
            lobe, exponent = np.zeros(len(hit)), np.zeros(len(hit))
            lobe[hit], exponent[hit] = strength[faces[hit]], shininess(roughness[faces[hit]])
            view = dataclasses.replace(view, specular=lobe, exponent=exponent)
        return view

    def set_scene(self, scene: Scene) -> None:
        """Replace the scene (a calibration board moved to its next pose); geometry is recomputed."""
        self.scene = scene
        self._scene_key, self._caster = memo.scene_caster(scene)
        self._views.clear()
        self._illumination.clear()
        self._truths.clear()

    def _lighting(self, camera: int, projector: int) -> _Illumination:
        key = (camera, projector)
        if key not in self._illumination:
            devices = (memo.device_key(self.cameras[camera]), memo.device_key(self.projectors[projector]))
            kept = memo.keyed(self._scene_key, *devices, self.projector_options[projector])
            self._illumination[key] = memo.remembered(
                "lighting", kept, lambda: self._compute_lighting(camera, projector)
            )
        return self._illumination[key]

    def _compute_lighting(self, camera: int, projector: int) -> _Illumination:
        view = self._view(camera)
        cam = self.cameras[camera]
        n_px = cam.width * cam.height
        uv = np.full((n_px, 2), np.nan)
        lit = np.zeros(n_px, dtype=bool)
        gain = np.zeros(n_px, dtype=np.float32)
        highlight = None if view.specular is None else np.zeros(n_px, dtype=np.float32)
        idx = np.flatnonzero(view.hit)
        for start in range(0, len(idx), _LIGHTING_CHUNK):  # chunks bound the temporaries
            part = idx[start : start + _LIGHTING_CHUNK]
            points, normals = view.points[part], view.normals[part]
            uv[part], lit[part], gain[part], to_light = self._light_points(projector, points, normals)
            if highlight is not None and view.exponent is not None and view.specular is not None:
                to_eye = _to_device(cam, points)
                lobe, exponent = view.specular[part], view.exponent[part]
                highlight[part] = specular_gain(normals, to_light, to_eye, lobe, exponent, gain[part])
        map_x = np.where(lit, uv[:, 0], -1e4).astype(np.float32)
        map_y = np.where(lit, uv[:, 1], -1e4).astype(np.float32)
        shape = (cam.height, cam.width)
        specular = None if highlight is None else highlight.reshape(shape)
        return _Illumination(map_x.reshape(shape), map_y.reshape(shape), gain.reshape(shape), uv, lit, specular)

    def _light_points(
        self, projector: int, points: np.ndarray, normals: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Projector pixel, lit flag, irradiance gain and unit direction to the light of surface points."""
        proj = self.projectors[projector]
        params = self.projector_options[projector]
        puv, pz = proj.project(points)
        inside = (
            (pz > 0)
            & (puv[:, 0] >= -0.5)
            & (puv[:, 0] < proj.width - 0.5)
            & (puv[:, 1] >= -0.5)
            & (puv[:, 1] < proj.height - 0.5)
        )
        if proj.projection == "orthographic":
            to_light = np.broadcast_to(-proj.axis, points.shape)
            distance = np.full(len(points), np.inf)
            falloff = np.ones(len(points))
        else:
            to_light = proj.center - points
            distance = np.linalg.norm(to_light, axis=1)
            to_light /= distance[:, None]
            falloff = (REFERENCE_DISTANCE_MM / distance) ** 2
        cos_i = np.einsum("ij,ij->i", normals, to_light)
        c_idx = np.flatnonzero(inside & (cos_i > 0))
        blocker, _ = self._caster.first_hit(points[c_idx] + _SHADOW_EPS_MM * normals[c_idx], to_light[c_idx])
        lit = np.zeros(len(points), dtype=bool)
        lit[c_idx[blocker >= distance[c_idx] - 2 * _SHADOW_EPS_MM]] = True
        gain = np.where(lit, cos_i * falloff * params.brightness, 0.0)
        return puv, lit, gain, to_light

    # --- rendering -------------------------------------------------------------------------
    def _segments(self, projector: int, start: float, duration: float) -> list[tuple[float, np.ndarray | None]]:
        """(weight, light) of what a projector emits during [start, start + duration]: a frame
        exposed across a pattern change sees both patterns, each for its share of the exposure."""
        end = start + duration
        changes = [t for t, _ in self._history[projector] if start < t < end]
        bounds = [start, *changes, end]
        if duration <= 0 or len(bounds) == 2:
            return [(1.0, self.emitted_at(projector, start))]
        return [
            (float((b - a) / duration), self.emitted_at(projector, a)) for a, b in itertools.pairwise(bounds) if b > a
        ]

    def irradiance(self, camera: int, time_s: float | None = None, duration_s: float = 0.0) -> np.ndarray:
        """Light falling on the surface seen by each camera pixel, averaged over
        [time_s, time_s + duration_s] of bench time (default: now, an instant), before albedo (float32)."""
        return self.gathered(camera, time_s, duration_s)

    def gathered(
        self, camera: int, time_s: float | None = None, duration_s: float = 0.0, specular: bool = False
    ) -> np.ndarray:
        """The projectors' light at each camera pixel over [time_s, time_s + duration_s]: the
        irradiance with the ambient (before albedo), or with `specular` the radiance of the
        surface's specular lobe toward the camera (drivers.sim.materials)."""
        cam = self.cameras[camera]
        when = self.clock_s if time_s is None else time_s
        total = np.full((cam.height, cam.width), 0.0 if specular else self.ambient, dtype=np.float32)
        scratch = np.empty_like(total)
        for p in range(len(self.projectors)):
            light = self._lighting(camera, p)
            gain = light.specular_gain if specular else light.irradiance_gain
            if gain is None:
                continue
            black = self.projector_options[p].black_level
            for weight, emitted in self._segments(p, when, duration_s):
                if emitted is None:
                    total += np.multiply(gain, np.float32(weight * black), out=scratch)
                    continue
                sampled = cv2.remap(  # into the scratch image: no image-sized array per frame
                    emitted,
                    light.map_x,
                    light.map_y,
                    cv2.INTER_LINEAR,
                    dst=scratch,
                    borderMode=cv2.BORDER_CONSTANT,
                    borderValue=0,
                )
                sampled *= np.float32(weight)  # in place, in the order (weight * light) * gain
                sampled *= gain
                total += sampled
        return total

    def render(
        self, camera: int, exposure_us: float | None = None, gain: float | None = None, time_s: float | None = None
    ) -> np.ndarray:
        """One camera image of the light at bench time `time_s` (default now), with sensor noise,
        as uint8 or uint16; the bench clock moves on by a frame period."""
        sensor, params = self.camera_settings[camera], self.camera_options[camera]
        exposure = sensor.exposure_us if exposure_us is None else exposure_us
        gain = sensor.gain if gain is None else gain
        view = self._view(camera)
        irradiance = self.irradiance(camera, time_s, exposure * 1e-6 if time_s is not None else 0.0)
        if sensor.color:
            radiance = irradiance[..., None] * view.albedo
        else:
            radiance = np.multiply(irradiance, view.albedo_mono, out=irradiance)
        if view.specular is not None:  # a highlight is the light's colour, not the surface's
            highlight = self.gathered(camera, time_s, exposure * 1e-6 if time_s is not None else 0.0, specular=True)
            radiance += highlight[..., None] if sensor.color else highlight
        self.clock_s += max(params.frame_period_s, exposure * 1e-6)
        return expose(radiance, exposure, gain, sensor, params, self._noise)

    # --- ground truth ----------------------------------------------------------------------
    def cast(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """True surface points (N, 3; NaN on a miss) and unit normals along arbitrary rays, for
        measuring reconstructions at sub-pixel positions."""
        distance, faces = self._caster.first_hit(np.asarray(origins, float), np.asarray(directions, float))
        hit = faces >= 0
        points = np.full((len(faces), 3), np.nan)
        points[hit] = origins[hit] + distance[hit, None] * directions[hit]
        normals = np.full((len(faces), 3), np.nan)
        normals[hit] = self._caster.face_normals(faces[hit])
        return points, normals

    def ground_truth(self, camera: int, projector: int) -> PixelTruth:
        """The pair's truth: the same object until the scene changes."""
        if (camera, projector) not in self._truths:
            self._truths[camera, projector] = self._pixel_truth(camera, projector)
        return self._truths[camera, projector]

    def _pixel_truth(self, camera: int, projector: int) -> PixelTruth:
        view = self._view(camera)
        light = self._lighting(camera, projector)
        cam = self.cameras[camera]
        shape = (cam.height, cam.width)
        return PixelTruth(
            hit=view.hit.reshape(shape),
            points=view.points.reshape(*shape, 3),
            normals=view.normals.reshape(*shape, 3),
            depth=view.depth.reshape(shape),
            projector_uv=light.uv.reshape(*shape, 2),
            lit=light.lit.reshape(shape),
            albedo=view.albedo[..., ::-1],
            white_irradiance=self.ambient + light.irradiance_gain,
            seen=view.seen,
        )


def _to_device(device: ViewModel, points: np.ndarray) -> np.ndarray:
    """Unit directions from surface points to a device (its centre; along its axis if orthographic)."""
    if device.projection == "orthographic":
        return np.broadcast_to(-device.axis, points.shape).copy()
    toward = device.center - points
    return toward / np.linalg.norm(toward, axis=1, keepdims=True)
