"""A device under contract, with what a test can observe of it and how to make it fail."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Generic, TypeVar

import pytest

from drivers.base import Device
from drivers.faults import Fault, FaultPlan

D = TypeVar("D", bound=Device)

FAULT_GRACE_S = 0.5  # beyond a device's own timeout: darkening, a worker's exit


@dataclass
class Kit(Generic[D]):
    device: D  # not yet open
    timeout_s: float = 2.0  # the longest wait the device's driver promises
    is_dark: Callable[[], bool] | None = None  # projectors: no light leaves it (None: cannot tell)
    is_blanked: Callable[[], bool] | None = None  # power controls: the picture is muted
    input_name: str = "hdmi"  # power controls: an input the device has
    buffers: bool = True  # cameras: the driver holds frames, so a capture after a pause is stale
    arm: Callable[[], None] | None = None  # starts the planned fault now (None: planned at build)
    now: Callable[[], float] = time.monotonic  # the clock of the device's stamps
    wait: Callable[[float], None] = time.sleep  # let time pass on that clock
    cleanup: list[Callable[[], None]] = field(default_factory=list)

    def close(self) -> None:
        self.device.close()
        for step in reversed(self.cleanup):
            step()


class Contract(Generic[D]):
    """The fixtures every contract shares; subclasses define make_kit."""

    def make_kit(self, plan: FaultPlan | None = None) -> Kit[D] | None:
        """The device to test with `plan` armed (None: no fault); None when this device cannot
        be made to fail that way (the test is skipped, saying so)."""
        raise NotImplementedError

    @pytest.fixture
    def kit(self) -> Iterator[Kit[D]]:
        made = self.make_kit()
        assert made is not None
        yield made
        made.close()

    def faulty(self, fault: Fault, after: int = 0) -> Kit[D]:
        made = self.make_kit(FaultPlan(fault, after))
        if made is None:
            pytest.skip(f"{type(self).__name__}: this device cannot be made to fail with {fault}")
        return made


def fails_within(limit_s: float, action: Callable[[], object], expected: type[BaseException]) -> BaseException:
    """Run `action`, which must raise `expected` within `limit_s`; the exception."""
    start = time.monotonic()
    with pytest.raises(expected) as caught:
        action()
    elapsed = time.monotonic() - start
    assert elapsed < limit_s, f"failed only after {elapsed:.2f} s (promised {limit_s:.2f} s)"
    return caught.value
