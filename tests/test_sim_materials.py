"""Materials on the simulated bench (drivers.sim.materials, drivers.sim.sensor): a glossy object's
highlight clips the camera where a matte one does not, the truth is the same for both, and a pixel
holds no more charge than its well."""

from __future__ import annotations

import numpy as np

from drivers.options import CameraSettings, SimCameraOptions
from drivers.sim.materials import shininess, specular_gain
from drivers.sim.sensor import NoiseTable, expose
from drivers.sim.truth import PixelTruth
from rig.assembly import open_rig
from rig.config import config_from_dict
from tests.conftest import small_config_data


def _white_frame(specular: float, roughness: float = 0.1) -> tuple[np.ndarray, PixelTruth]:
    data = small_config_data()
    data["simulation"]["material"] = {"specular": specular, "roughness": roughness}
    with open_rig(config_from_dict(data, "materials")) as rig:
        bench = rig.truth
        assert bench is not None
        projector = rig.projectors[0]
        width, height = projector.resolution
        projector.show(np.full((height, width), 255, np.uint8))
        frame = rig.cameras[0].capture(timeout_s=5.0).image
        truth = bench.ground_truth(0, 0)
        return frame, truth


def test_a_glossy_highlight_clips_where_the_matte_surface_does_not() -> None:
    matte, matte_truth = _white_frame(0.0)
    glossy, glossy_truth = _white_frame(0.6)
    assert matte.max() < 255  # the bench's matte grey stays below full scale
    clipped = glossy >= 255
    assert 0 < clipped.sum() < 0.05 * clipped.size  # a highlight, not the whole sphere
    assert np.array_equal(matte_truth.hit, glossy_truth.hit) and np.array_equal(matte_truth.lit, glossy_truth.lit)
    np.testing.assert_array_equal(matte_truth.points, glossy_truth.points)  # gloss is no change of shape
    away = ~clipped & matte_truth.hit
    # away from the highlight the lobe adds little: the same surface, about the same brightness
    assert np.median(np.abs(glossy[away].astype(int) - matte[away].astype(int))) <= 3


def test_the_lobe_peaks_at_the_mirror_direction_and_narrows_with_roughness() -> None:
    normal = np.array([[0.0, 0.0, 1.0]])
    to_light = np.array([[np.sin(0.4), 0.0, np.cos(0.4)]])
    mirror = np.array([[-np.sin(0.4), 0.0, np.cos(0.4)]])
    aside = np.array([[-np.sin(0.6), 0.0, np.cos(0.6)]])
    one = np.ones(1)
    for roughness in (0.05, 0.2):
        s = shininess(roughness) * one
        peak = specular_gain(normal, to_light, mirror, 0.5 * one, s, one)[0]
        assert peak == np.float32(0.5 * (s[0] + 8) / 8)  # n . h = 1 at the mirror direction
        off = specular_gain(normal, to_light, aside, 0.5 * one, s, one)[0]
        assert off < peak
    ratio = [
        specular_gain(normal, to_light, aside, one, shininess(r) * one, one)[0] / (shininess(r) + 8)
        for r in (0.05, 0.2)
    ]
    assert ratio[0] < ratio[1]  # 0.1 rad off the mirror: the polished lobe has fallen further
    assert specular_gain(normal, to_light, mirror, one, shininess(0.1) * one, np.zeros(1))[0] == 0.0  # unlit


def test_a_pixel_holds_no_more_charge_than_its_well() -> None:
    params = SimCameraOptions(read_noise_e=0.0)
    sensor = CameraSettings()
    radiance = np.full((4, 4), 50.0, np.float32)  # far over full scale at the set exposure
    at_half_gain = expose(
        radiance.copy(), sensor.exposure_us, 0.5, sensor, params, NoiseTable(np.random.default_rng(0))
    )
    assert np.all(at_half_gain == round(0.5 ** (1.0 / params.gamma) * sensor.full_scale))  # the well, not the converter
