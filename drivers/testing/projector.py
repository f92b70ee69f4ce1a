"""What every projector promises: dark when opened, closed or failed; patterns only when open and
of its own size; every wait finite."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.base import Projector, ProjectorMode
from drivers.errors import DeviceError, DeviceStateError
from drivers.faults import Fault
from drivers.sequences import PatternSequence, SequenceEntry, TriggerMode
from drivers.testing.kit import FAULT_GRACE_S, Contract, Kit, fails_within

SEQUENCE = PatternSequence(tuple(SequenceEntry(i % 3, 8) for i in range(6)), 8333, 8333, TriggerMode.EXTERNAL)


def light(projector: Projector, value: int = 255) -> None:
    """Put light out: a full-frame pattern, or a sequence started."""
    width, height = projector.resolution
    pattern = np.full((height, width), value, np.uint8)
    if projector.mode is ProjectorMode.STREAMING:
        projector.show(pattern)
    else:
        projector.load_sequence(
            PatternSequence(SEQUENCE.entries, SEQUENCE.exposure_us, SEQUENCE.period_us, images=(pattern,) * 6)
        )
        projector.start_sequence()


class ProjectorContract(Contract[Projector]):
    def test_open_is_dark_and_close_is_idempotent(self, kit: Kit[Projector]) -> None:
        kit.device.open()
        assert kit.device.is_open
        if kit.is_dark is not None:
            assert kit.is_dark()
        kit.device.close()
        kit.device.close()
        assert not kit.device.is_open

    def test_a_closed_projector_refuses_work_but_can_always_go_dark(self, kit: Kit[Projector]) -> None:
        kit.device.dark()  # never raises, even closed
        with pytest.raises(DeviceStateError):
            light(kit.device)

    def test_patterns_light_it_and_dark_stops_the_light(self, kit: Kit[Projector]) -> None:
        kit.device.open()
        light(kit.device)
        if kit.is_dark is not None:
            assert not kit.is_dark()
        kit.device.dark()
        if kit.is_dark is not None:
            assert kit.is_dark()

    def test_the_wrong_way_to_show_is_a_state_error(self, kit: Kit[Projector]) -> None:
        projector = kit.device
        projector.open()
        width, height = projector.resolution
        with pytest.raises(DeviceStateError):
            if projector.mode is ProjectorMode.STREAMING:
                projector.load_sequence(SEQUENCE)
            else:
                projector.show(np.zeros((height, width), np.uint8))

    def test_a_still_image_lights_it_or_is_a_state_error_and_dark_stops_it(self, kit: Kit[Projector]) -> None:
        projector = kit.device
        projector.open()
        width, height = projector.resolution
        still = np.full((height, width), 255, np.uint8)
        try:
            projector.show_still(still)  # a setup pattern, in either mode where the device can
        except DeviceStateError:
            assert projector.mode is ProjectorMode.SEQUENCE  # only a sequence projector may refuse it
        else:
            if kit.is_dark is not None:
                assert not kit.is_dark()
        projector.dark()
        if kit.is_dark is not None:
            assert kit.is_dark()
        with pytest.raises(ValueError):
            projector.show_still(still[1:])

    def test_a_pattern_of_another_size_is_refused(self, kit: Kit[Projector]) -> None:
        projector = kit.device
        projector.open()
        width, height = projector.resolution
        with pytest.raises(ValueError):
            if projector.mode is ProjectorMode.STREAMING:
                projector.show(np.zeros((height + 1, width), np.uint8))
            else:
                projector.load_sequence(PatternSequence(SEQUENCE.entries, 8333, 8333, images=(np.zeros((2, 2)),)))

    @pytest.mark.parametrize("fault", [Fault.SILENCE, Fault.DISCONNECT])
    def test_a_fault_fails_within_the_timeout_and_leaves_it_dark(self, fault: Fault) -> None:
        kit = self.faulty(fault)
        try:
            kit.device.open()
            light(kit.device, 200)
            if kit.arm is not None:
                kit.arm()

            def keep_lighting() -> None:
                for _ in range(3):  # a pipe or socket may take a write to notice
                    light(kit.device, 100)

            fails_within(kit.timeout_s * 3 + FAULT_GRACE_S, keep_lighting, DeviceError)
            if kit.is_dark is not None:
                assert kit.is_dark()
        finally:
            kit.close()
