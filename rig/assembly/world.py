"""Where a rig's devices live: the real world or the simulated bench. The assembly hands the world
to every device factory, and the world gives the rig its clock and, where it has them, ground
truth and control of the scene."""

from __future__ import annotations

from dataclasses import dataclass, field

from rig.opened_rig import Clock, GroundTruth, MonotonicClock, SceneControl


@dataclass
class World:
    """Real devices: the host's clock; no ground truth, no hand on the scene."""

    clock: Clock = field(default_factory=MonotonicClock)
    truth: GroundTruth | None = None
    scene: SceneControl | None = None
