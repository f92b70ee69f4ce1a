"""A LightCrafter 4500 fed its patterns over HDMI and told over USB how to play them.

The display worker puts up to three 8-bit patterns on the LightCrafter's video input as one RGB
frame (pattern 0 in green, 1 in red, 2 in blue: the DLPC350's bit-plane groups of a 24-bit frame).
The controller, in pattern mode with the video port as source and VSYNC as trigger, plays that
frame's patterns one after another, each for the pattern period, and frames each exposure with a
TRIG_OUT_1 pulse that starts the cameras' exposures.

With `sequence=False` it is a streaming projector instead: video mode, each pattern shown on the
input as grey, and dark meaning the LEDs off (for software sync and cameras without a trigger).
A sequence projector shows a still image (a setup pattern, `show_still`) the same way, in video
mode, until the next sequence is loaded.

Each video frame of a sequence is played as its own group: show the frame, wait `input_latency_s` until it sits
in the controller's buffer (the user guide gives one frame of delay from the input), then start
the one-frame LUT (VSYNC trigger, no repeat), which plays the frame's patterns once and stops. So
no pattern depends on the worker's page flips landing on a particular VSYNC.

Assumptions not yet checked on a bench (TI's documents leave them open): a stopped one-frame LUT
restarts from its first entry on START without a new validation, and LUT trigger code 0 means
"wait for VSYNC" in VSYNC mode with code 3 ("no trigger") for the frame's later patterns.
"""

from __future__ import annotations

import contextlib
import os
import time

import numpy as np

from drivers.base import Projector, ProjectorMode
from drivers.dlp.lcr4500 import Lcr4500Projector
from drivers.errors import DeviceStateError
from drivers.hdmi import projector as hdmi
from drivers.hdmi.projector import HdmiProjector
from drivers.machine import attached_usb
from drivers.options import DeviceConfig
from drivers.sequences import PatternSequence, SequenceEntry, TriggerMode

CHANNEL_OF_PATTERN = (1, 0, 2)  # 8-bit pattern k of a frame is green, red, blue (RGB indices)
PATTERN_BIT_DEPTH = 8


def pack_frames(images: tuple[np.ndarray, ...] | list[np.ndarray], per_frame: int) -> list[np.ndarray]:
    """RGB video frames carrying `per_frame` 8-bit patterns each; unused channels are black."""
    if not 1 <= per_frame <= 3:
        raise ValueError(f"a 24-bit frame carries 1 to 3 eight-bit patterns, not {per_frame}")
    height, width = images[0].shape
    frames = []
    for start in range(0, len(images), per_frame):
        frame = np.zeros((height, width, 3), np.uint8)
        for k, image in enumerate(images[start : start + per_frame]):
            frame[:, :, CHANNEL_OF_PATTERN[k]] = image
        frames.append(frame)
    return frames


class LightCrafterHdmiProjector(Projector):
    """A projector made of the LightCrafter's USB control and an HDMI display output."""

    @classmethod
    def from_config(cls, device: DeviceConfig) -> LightCrafterHdmiProjector:
        """The LightCrafter a config's `lightcrafter` section (USB control) and `hdmi` section
        (its video input) describe; with sync hardware it plays whole sequences."""
        lc = device.lightcrafter
        control = Lcr4500Projector(f"{device.name}-usb", lc.serial_number, lc.usb_timeout_s)
        video = HdmiProjector.from_config(device)
        sequence = device.sync == "hardware"
        return cls(device.name, control, video, sequence, lc.patterns_per_frame, lc.input_latency_s)

    def __init__(
        self,
        name: str,
        control: Lcr4500Projector,
        video: HdmiProjector,
        sequence: bool = True,
        patterns_per_frame: int = 2,
        input_latency_s: float = 0.05,
    ) -> None:
        super().__init__(name)
        self.mode = ProjectorMode.SEQUENCE if sequence else ProjectorMode.STREAMING
        if video.resolution != control.resolution:
            raise ValueError(f"{name}: the video output must be {control.resolution}, got {video.resolution}")
        if not 1 <= patterns_per_frame <= 3:
            raise ValueError(f"{name}: patterns_per_frame must be 1 to 3")
        self.control = control
        self.video = video
        self.patterns_per_frame = patterns_per_frame
        self.input_latency_s = input_latency_s
        self._frames: list[np.ndarray] = []
        self._lit = False

    @property
    def resolution(self) -> tuple[int, int]:
        return self.control.resolution

    def _do_open(self) -> None:
        self.video.open()  # the input goes black first
        try:
            self.control.open()  # dark: LEDs off whatever the input shows
            if self.mode is ProjectorMode.STREAMING:
                self.control.video_mode(lit=False)
        except Exception:
            self.video.close()
            raise
        self._lit = False

    def _do_close(self) -> None:
        try:
            self.control.close()
        finally:
            self.video.close()

    def _do_dark(self) -> None:
        self._lit = False
        try:
            self.control.dark()  # the light itself; the input going black is a second line
        finally:
            self.video.dark()

    def _do_show(self, pattern: np.ndarray) -> None:
        self.video.show(pattern)
        self.last_present_s = self.video.last_present_s
        if not self._lit:
            self.control.lights_on()
            self._lit = True

    def _do_show_still(self, image: np.ndarray) -> None:
        """Out of pattern mode: the controller shows its video input, lit, as in streaming mode;
        the next load_sequence puts it back into pattern mode."""
        self.video.show(image)
        self.last_present_s = self.video.last_present_s
        self.control.video_mode(lit=True)
        self._lit = True

    def sequence_groups(self, count: int) -> list[int]:
        frames = -(-count // self.patterns_per_frame)
        return [self.patterns_per_frame] * frames

    def _do_load_sequence(self, sequence: PatternSequence) -> None:
        if sequence.images is None:
            raise DeviceStateError(f"{self.name}: patterns reach it over HDMI; give sequence.images")
        self._frames = []
        one_frame = PatternSequence(
            entries=tuple(SequenceEntry(k, PATTERN_BIT_DEPTH) for k in range(self.patterns_per_frame)),
            exposure_us=sequence.exposure_us,
            period_us=sequence.period_us,
            trigger=TriggerMode.VSYNC,
            source="video",
        )
        self.control.load_sequence(one_frame)  # the controller validates the timing
        self._frames = pack_frames(sequence.images, self.patterns_per_frame)

    def _do_start_sequence(self, group: int = 0) -> None:
        if not 0 <= group < len(self._frames):
            raise DeviceStateError(f"{self.name}: no video frame {group} loaded ({len(self._frames)} frames)")
        if group > 0:
            self.control.stop_sequence()  # back to the LUT's first entry, dark meanwhile
        self.video.show_rgb(self._frames[group])
        self.last_present_s = self.video.last_present_s
        time.sleep(self.input_latency_s)  # until the controller holds this frame
        self.control.start_sequence()
        self._lit = True

    def _do_stop_sequence(self) -> None:
        try:
            self.control.stop_sequence()
        finally:
            with contextlib.suppress(Exception):  # the LEDs are off; the input is the second line
                self.video.dark()


LIGHTCRAFTER_USB = (0x0451, 0x6401)  # the DLPC350's USB id


def machine_problems(device: DeviceConfig) -> list[str]:
    """What this machine lacks to drive a LightCrafter 4500: the board on USB, a node the service
    user may open, and its HDMI output (slrig doctor)."""
    listing = attached_usb()
    if "error" in listing:
        return [str(listing["error"]), *hdmi.machine_problems(device)]
    found = [d for d in listing["devices"] if (d["vid"], d["pid"]) == LIGHTCRAFTER_USB]
    if not found:
        problem = "no LightCrafter 4500 (USB 0451:6401) attached: is it powered and its USB cable in?"
        return [problem, *hdmi.machine_problems(device)]
    bus, address = found[0]["bus"], found[0]["address"]
    node = f"/dev/bus/usb/{bus:03d}/{address:03d}" if bus is not None and address is not None else ""
    problems = []
    if node and os.path.exists(node) and not os.access(node, os.R_OK | os.W_OK):
        problems.append(f"no access to {node}: install systemd/60-slrig.rules and add the service user to 'plugdev'")
    return problems + hdmi.machine_problems(device)
