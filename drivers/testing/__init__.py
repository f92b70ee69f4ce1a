"""Contract suites: what every projector, camera and power control promises, as pytest classes.

A test module subclasses a contract and defines `make_kit(plan)`: the device to test (not yet
open), how to observe it where that is possible, and how to arm a fault (drivers.faults).
The same suites run against the simulated devices, every real driver on its protocol fake, and,
with `pytest --rig bench.yaml`, the devices of a real bench.
"""

from drivers.testing.camera import CameraContract
from drivers.testing.kit import Kit
from drivers.testing.power import PowerControlContract
from drivers.testing.projector import ProjectorContract

__all__ = ["CameraContract", "Kit", "PowerControlContract", "ProjectorContract"]
