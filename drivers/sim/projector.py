"""The simulated projector: the real Projector interface over the SimBench model."""

from __future__ import annotations

import numpy as np

from drivers.base import Projector, ProjectorMode
from drivers.errors import DeviceStateError
from drivers.sequences import PatternSequence
from drivers.sim.bench import SimBench


class SimProjector(Projector):
    """A projector whose light falls on the simulated scene: streaming (each show() is lit after its
    latency) or, with `sequence=True`, one that plays a preloaded sequence on its own clock and
    pulses its trigger output at each pattern, like a LightCrafter in pattern mode."""

    def __init__(self, name: str, bench: SimBench, index: int, sequence: bool = False) -> None:
        super().__init__(name)
        self._bench = bench
        self._index = index
        self.mode = ProjectorMode.SEQUENCE if sequence else ProjectorMode.STREAMING
        self.shown = 0  # patterns shown since open, for tests
        self._loaded: PatternSequence | None = None

    @property
    def resolution(self) -> tuple[int, int]:
        model = self._bench.projectors[self._index]
        return model.width, model.height

    @property
    def is_dark(self) -> bool:
        """No light now and none on its way (a playing sequence is lit until its last pattern ends)."""
        now = self._bench.clock_s
        scheduled = [light for start, light in self._bench._history[self._index] if start > now]
        return self._bench.emitted_at(self._index, now) is None and all(light is None for light in scheduled)

    def _do_open(self) -> None:
        self._bench.set_pattern(self._index, None)

    def _do_show(self, pattern: np.ndarray) -> None:
        self._bench.set_pattern(self._index, pattern)
        self.last_present_s = self._bench.clock_s
        self.shown += 1

    def _do_dark(self) -> None:
        self._bench.set_pattern(self._index, None)

    def _do_show_still(self, image: np.ndarray) -> None:  # in sequence mode, as a LightCrafter's video mode
        self._do_show(image)

    def _do_load_sequence(self, sequence: PatternSequence) -> None:
        if sequence.images is None:
            raise DeviceStateError(f"{self.name}: the simulated projector plays images; give sequence.images")
        self._loaded = sequence

    def _do_start_sequence(self, group: int = 0) -> None:
        if self._loaded is None or self._loaded.images is None:
            raise DeviceStateError(f"{self.name}: no sequence loaded")
        self._bench.play(self._index, list(self._loaded.images), self._loaded.period_us * 1e-6)
        self.shown += len(self._loaded.images)

    def _do_stop_sequence(self) -> None:
        self._bench.set_pattern(self._index, None)
