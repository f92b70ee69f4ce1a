"""The LightCrafter 4500 fed over HDMI: the real USB driver on its protocol fake and the real display
worker (offscreen), packing patterns into video frames, and a hardware-synced scan of the
simulated bench through them that gives the software-synced cloud."""

from __future__ import annotations

import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from drivers.base import ProjectorMode
from drivers.dlp.hdmi_patterns import CHANNEL_OF_PATTERN, LightCrafterHdmiProjector, pack_frames
from drivers.dlp.lcr4500 import PRODUCT_ID, RESOLUTION, VENDOR_ID, Lcr4500Projector
from drivers.errors import DeviceProtocolError
from drivers.fakes.dlpc350 import FakeLcr4500, finder_for
from drivers.hdmi.projector import HdmiProjector
from drivers.sequences import PatternSequence, SequenceEntry, TriggerMode
from drivers.sim.bench import SimBench
from drivers.usbhid import PyUsbHidTransport
from rig.assembly import open_rig
from rig.config import load_config
from rig.errors import ConfigError
from rig.evaluate.pairs import evaluate_on_bench
from rig.pipeline.scan import run_scan
from tests.conftest import small_config_data, write_config

WIDTH, HEIGHT = RESOLUTION


def _patterns(count: int) -> list[np.ndarray]:
    rng = np.random.default_rng(count)
    return [rng.integers(0, 256, (HEIGHT, WIDTH), dtype=np.uint8) for _ in range(count)]


class _Kit:
    """The composite projector on a fake LightCrafter; `shown` is every RGB frame it put on HDMI."""

    def __init__(self, sequence: bool = True, per_frame: int = 2, fake: FakeLcr4500 | None = None) -> None:
        self.fake = fake or FakeLcr4500()
        control = Lcr4500Projector(
            "lcr-usb",
            timeout_s=0.5,
            validate_timeout_s=0.3,
            transport_factory=lambda: PyUsbHidTransport(VENDOR_ID, PRODUCT_ID, finder=finder_for(self.fake)),
        )
        self.video = HdmiProjector("lcr-hdmi", RESOLUTION, video_driver="offscreen")
        self.shown: list[np.ndarray] = []
        show_rgb = self.video.show_rgb

        def spy(frame: np.ndarray) -> None:  # the HDMI cable: what the LightCrafter's input receives
            show_rgb(frame)
            self.shown.append(frame)

        self.video.show_rgb = spy  # type: ignore[method-assign]
        self.projector = LightCrafterHdmiProjector(
            "lcr", control, self.video, sequence=sequence, patterns_per_frame=per_frame, input_latency_s=0.0
        )


@pytest.fixture
def kit() -> Iterator[_Kit]:
    k = _Kit()
    yield k
    k.projector.close()


def _sequence(images: list[np.ndarray], period_us: int = 8333) -> PatternSequence:
    entries = tuple(SequenceEntry(k % 3, 8) for k in range(len(images)))
    return PatternSequence(entries, period_us, period_us, TriggerMode.INTERNAL, images=tuple(images))


def test_patterns_are_packed_green_red_blue() -> None:
    images = _patterns(5)
    frames = pack_frames(images, 2)
    assert len(frames) == 3
    assert np.array_equal(frames[0][:, :, 1], images[0]) and np.array_equal(frames[0][:, :, 0], images[1])
    assert not frames[0][:, :, 2].any()  # the unused blue channel is black
    assert np.array_equal(frames[2][:, :, 1], images[4]) and not frames[2][:, :, 0].any()
    three = pack_frames(images[:3], 3)
    assert [np.array_equal(three[0][:, :, CHANNEL_OF_PATTERN[k]], images[k]) for k in range(3)] == [True] * 3


def test_each_video_frame_plays_its_patterns_on_vsync(kit: _Kit) -> None:
    images = _patterns(5)
    projector, fake = kit.projector, kit.fake
    projector.open()
    assert fake.dark and projector.video.is_dark
    projector.load_sequence(_sequence(images))
    assert (fake.display_mode, fake.source, fake.trigger_mode) == (1, 0, 0)  # pattern mode, video port, VSYNC
    words = fake.lut_entries
    assert [(w >> 2) & 0x3F for w in words] == [0, 1]  # one frame's LUT: green, then red
    assert [w & 0x3 for w in words] == [1, 3]  # the first waits for VSYNC (trigger 1, as TI's GUI), the second follows
    assert [bool(w & (1 << 18)) for w in words] == [True, False]  # the frame's buffer is swapped in once
    assert projector.sequence_groups(5) == [2, 2, 2]
    for group in range(3):
        projector.start_sequence(group)
        assert fake.running and not fake.dark
        assert kit.video.last_checksum == zlib.crc32(kit.shown[-1].tobytes())  # the worker shows that frame
        assert np.array_equal(kit.shown[-1][:, :, 1], images[2 * group])
    assert fake.starts == 3
    projector.stop_sequence()
    assert not fake.running and fake.dark and kit.video.is_dark


def test_a_setup_pattern_is_shown_in_video_mode_and_the_next_sequence_plays_as_before(kit: _Kit) -> None:
    projector, fake = kit.projector, kit.fake
    projector.open()
    still = _patterns(1)[0]
    projector.show_still(still)  # aiming and focusing: the input as it is, lit
    assert fake.display_mode == 0 and not fake.dark and not fake.running
    assert kit.video.last_checksum == zlib.crc32(still.tobytes())
    projector.dark()
    assert fake.dark and kit.video.is_dark
    images = _patterns(2)
    projector.load_sequence(_sequence(images))
    assert (fake.display_mode, fake.source, fake.trigger_mode) == (1, 0, 0)  # back in pattern mode
    projector.start_sequence(0)
    assert fake.running and not fake.dark and np.array_equal(kit.shown[-1][:, :, 1], images[0])
    projector.stop_sequence()
    with pytest.raises(ValueError, match="uint8 of shape"):
        projector.show_still(still[:10])
    assert fake.dark


def test_a_frame_the_controller_cannot_play_is_refused_and_it_stays_dark() -> None:
    k = _Kit(per_frame=3)  # three 8-bit patterns of 8333 us do not fit in a 60 Hz frame
    try:
        k.projector.open()
        with pytest.raises(DeviceProtocolError, match="exposure or frame period invalid"):
            k.projector.load_sequence(_sequence(_patterns(3)))
        assert k.fake.dark and not k.fake.running
    finally:
        k.projector.close()


def test_in_video_mode_it_is_a_display_whose_dark_is_leds_off() -> None:
    k = _Kit(sequence=False)
    try:
        k.projector.open()
        assert k.projector.mode is ProjectorMode.STREAMING
        assert k.fake.display_mode == 0 and k.fake.dark  # video mode, LEDs off until a pattern
        k.projector.show(_patterns(1)[0])
        assert not k.fake.dark and k.projector.last_present_s == k.video.last_present_s
        k.projector.dark()
        assert k.fake.dark and k.video.is_dark
    finally:
        k.projector.close()
    assert not k.fake.claimed and k.video.worker_pid is None


def _bench_config(sync: str) -> dict[str, Any]:
    data = small_config_data()
    proj = data["projectors"][0]
    proj["resolution"] = list(RESOLUTION)
    proj["geometry"]["intrinsics"] = {"fx": 1600.0, "fy": 1600.0, "cx": 455.5, "cy": 569.5}
    proj["sync"] = sync
    proj["pattern_period_us"] = 8333
    data["cameras"][0]["exposure_us"] = 8000.0  # within one pattern
    return data


def test_a_hardware_synced_scan_through_the_lightcrafter_gives_the_software_synced_cloud(tmp_path: Path) -> None:
    with open_rig(load_config(write_config(tmp_path, _bench_config("software"), "software.yaml"))) as the_rig:
        software = evaluate_on_bench(the_rig, run_scan(the_rig, "gray").pairs[0])

    fake = FakeLcr4500()
    k = _Kit(fake=fake)
    with open_rig(load_config(write_config(tmp_path, _bench_config("hardware"), "hardware.yaml"))) as the_rig:
        bench = the_rig.truth  # the simulated bench is its own ground truth
        assert isinstance(bench, SimBench)

        def light_the_scene(device: FakeLcr4500) -> None:  # the DMD: the LUT's channels of the input frame
            bench.play(0, device.displayed_patterns(k.shown[-1]), device.period_us * 1e-6)

        fake.on_start = light_the_scene
        the_rig.projectors[0].close()
        the_rig.projectors[0] = k.projector
        k.projector.open()
        hardware = evaluate_on_bench(the_rig, run_scan(the_rig, "gray").pairs[0])
        assert fake.dark and k.video.is_dark
    assert fake.starts == len(k.shown) >= 10
    assert hardware["points"] == software["points"]
    assert hardware["rms_mm"] == pytest.approx(software["rms_mm"], rel=1e-9)


def test_config_checks_the_lightcrafter_timing(tmp_path: Path) -> None:
    data = _bench_config("hardware")
    data["projectors"][0]["driver"] = "lightcrafter"
    data["projectors"][0]["pattern_period_us"] = 9000
    data["cameras"][0]["driver"] = "oak"
    data.pop("simulation")
    with pytest.raises(ConfigError, match=r"projectors\[0\].*do not fit in a 60 Hz video frame"):
        load_config(write_config(tmp_path, data))
    data["projectors"][0]["pattern_period_us"] = 8333
    load_config(write_config(tmp_path, data))
    data["cameras"][0]["driver"] = "v4l2"
    data["cameras"][0]["v4l2"] = {"device": "/dev/video0"}
    with pytest.raises(ConfigError, match=r"cameras\[0\].driver: a v4l2 camera has no trigger input"):
        load_config(write_config(tmp_path, data))
