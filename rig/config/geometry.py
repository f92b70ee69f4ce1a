"""Device geometry in a config: intrinsics, distortion, pose, projection."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from rig.config.common import Strict, Vec3


class Intrinsics(Strict):
    """Pixels; for an orthographic device fx, fy are pixels per millimetre."""

    fx: float = Field(gt=0, le=1e6)
    fy: float = Field(gt=0, le=1e6)
    cx: float = Field(ge=-1e5, le=1e5)
    cy: float = Field(ge=-1e5, le=1e5)
    skew: float = Field(0.0, ge=-1e4, le=1e4)


class Pose(Strict):
    """Where the device is and what it looks at, in the world frame (bench plane z = 0, z up)."""

    position_mm: Vec3
    look_at_mm: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)

    @model_validator(mode="after")
    def _well_posed(self) -> Pose:
        view = np.subtract(self.look_at_mm, self.position_mm)
        if np.linalg.norm(view) < 1e-6:
            raise ValueError("look_at_mm must differ from position_mm")
        if np.linalg.norm(np.cross(view / np.linalg.norm(view), self.up)) < 1e-6:
            raise ValueError("up must not be parallel to the viewing direction")
        return self


class Geometry(Strict):
    """Ground-truth (simulation) or calibrated geometry of one device."""

    intrinsics: Intrinsics
    distortion: list[Annotated[float, Field(ge=-10.0, le=10.0)]] = Field(
        default_factory=list, max_length=5, description="k1, k2, p1, p2, k3"
    )
    pose: Pose
    projection: Literal["pinhole", "orthographic"] = "pinhole"
