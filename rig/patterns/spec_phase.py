"""The `phase` block of a pattern description (rig.patterns.spec): which fringes were shown, in
what order, and how their phase is unwrapped; checked against the projector it spans.

Frame n of a frequency shows 0.5 + 0.5 cos(2 pi x / P + start + s 2 pi n / N), s = +1 (shift
plus) or -1 (minus), x the projector coordinate (pixel centres at integers). The families:

- N-step phase shift of one or more periods per axis, the same for both axes or each its own
  (`frequencies: {columns: [...], rows: [...]}`), unwrapped by a Gray code of the period index,
  by heterodyne beats, or hierarchically (the longest period spans the projector);
- a single period that spans the projector (`unwrap: none`): no unwrapping, its coordinate as
  coarse as its phase noise times the period;
- micro phase shifting (Gupta & Nayar, CVPR 2012; `unwrap: micro`): periods in a narrow band,
  the first shown N >= 3 times shifted, every other once (n = 0); the first gives the phase, the
  others' single frames pick its period by the nearest of the projector's candidate columns;
- modulated phase shifting (Chen, Nayar et al., CVPR 2008; a `modulation` block): every phase
  frame shown M times, multiplied by a carrier 0.5 + 0.5 cos(2 pi y / Q + 2 pi m / M) along the
  other axis (y its coordinate), frame after frame for m = 0..M-1; the carrier's amplitude per
  pixel is the light that came straight from the projector, which the phase is read from.
"""

from __future__ import annotations

import math
from typing import Any, Literal, Protocol

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator


class Described(Protocol):
    """What check_unwrapping reads of a pattern description (rig.patterns.spec.PatternSpec, which
    imports this module)."""

    @property
    def phase(self) -> PhaseShift | None: ...

    @property
    def gray(self) -> Any: ...  # its Gray block: axes, reference

    def pixels(self, axis: Axis) -> int: ...


Axis = Literal["columns", "rows"]
MICRO_MARGIN = 0.25  # least distance, in fringe amplitudes, between two columns' micro readings (sum of squares)


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Frequency(Strict):
    period_px: float = Field(ge=2.0, le=65536.0, description="fringe period in projector pixels")
    steps: int = Field(ge=1, le=64, description="phase steps N of this period (3 or more; 1 for micro's others)")


class Modulation(Strict):
    """The carrier of modulated phase shifting, along the axis the fringes do not code."""

    period_px: float = Field(ge=2.0, le=256.0, description="the carrier's period in projector pixels")
    steps: int = Field(3, ge=3, le=16, description="carrier shifts M per phase frame")


class PhaseShift(Strict):
    """N-step phase shift of one or more frequencies per axis, and how its phase is unwrapped."""

    axes: tuple[Axis, ...] = Field(("columns",), min_length=1, max_length=2)
    frequencies: list[Frequency] | dict[Axis, list[Frequency]] = Field(
        description="in the order their frames come: one list for every axis, or a list per axis "
        "({columns: [...], rows: [...]})"
    )
    shift: Literal["plus", "minus"] = "plus"
    start_deg: float = Field(0.0, ge=-360.0, le=360.0)
    unwrap: Literal["gray", "heterodyne", "hierarchical", "micro", "none"] = Field(
        description="gray: a Gray code (the gray block) of the period index; heterodyne: the beats of 2 or 3 "
        "frequencies; hierarchical: the longest period spans the projector (a single-period cue) and unwraps "
        "the next shorter; micro: micro phase shifting (the first period N steps, the others one frame each); "
        "none: one period that spans the projector, read as it is (coarse)"
    )
    gray_unit: Literal["period", "half_period"] = Field(
        "period",
        description="unwrap gray: what the code counts; half_period (one bit more, slrig's phase codec) lets each "
        "pixel read the count whose edges lie a quarter period from its phase's wrap",
    )
    white_black: Literal["first", "last", "none"] = Field("none", description="without a gray block")
    min_modulation: float = Field(0.02, ge=0.0, le=1.0, description="least fringe amplitude, of full scale")
    modulation: Modulation | None = Field(None, description="modulated phase shifting: each phase frame M times")

    def of(self, axis: Axis) -> list[Frequency]:
        """The frequencies `axis` was shown, in the order their frames come."""
        return self.frequencies[axis] if isinstance(self.frequencies, dict) else self.frequencies

    @model_validator(mode="after")
    def _unwrappable(self) -> PhaseShift:
        if len(set(self.axes)) != len(self.axes):
            raise ValueError(f"axes {list(self.axes)}: an axis twice")
        if isinstance(self.frequencies, dict) and set(self.frequencies) != set(self.axes):
            raise ValueError(
                f"frequencies: lists for {sorted(self.frequencies)}, but the axes are {list(self.axes)}: one per axis"
            )
        for axis in self.axes:
            _check_counts(self, axis)
        return self


def _check_counts(phase: PhaseShift, axis: Axis) -> None:
    frequencies = phase.of(axis)
    where = f"frequencies ({axis})" if isinstance(phase.frequencies, dict) else "frequencies"
    count, unwrap = len(frequencies), phase.unwrap
    if not frequencies or count > (8 if unwrap == "micro" else 3):
        raise ValueError(f"{where}: {count} frequencies; 1 to 3 (micro: 2 to 8)")
    if unwrap in ("gray", "none") and count != 1:
        raise ValueError(f"unwrap {unwrap}: one frequency, not {count}")
    if unwrap in ("heterodyne", "hierarchical", "micro") and count < 2:
        raise ValueError(f"unwrap {unwrap}: two or more frequencies")
    for i, frequency in enumerate(frequencies):
        single = unwrap == "micro" and i > 0
        if single and frequency.steps != 1:
            raise ValueError(f"{where}[{i}].steps {frequency.steps}: micro phase shifting shows every period after "
                             "the first once (steps 1)")  # fmt: skip
        if not single and frequency.steps < 3:
            raise ValueError(f"{where}[{i}].steps {frequency.steps}: an N-step phase needs 3 or more")


def check_unwrapping(spec: Described) -> None:
    """The phase block's unwrapping can reach across the projector; ValueError naming the field
    and the numbers."""
    phase = spec.phase
    assert phase is not None
    if phase.unwrap == "gray":
        if spec.gray is None:
            raise ValueError("phase.unwrap gray: the gray block (the period index's code) is missing")
        if spec.gray.axes != phase.axes:
            raise ValueError(f"gray.axes {list(spec.gray.axes)}: must be phase.axes {list(phase.axes)}")
        if spec.gray.reference == "threshold" and phase.white_black != "none":
            raise ValueError("phase.white_black: the gray block's white_black places them")
        for axis in phase.axes:
            if phase.of(axis)[0].period_px >= spec.pixels(axis):
                raise ValueError(
                    f"phase.frequencies ({axis}): a period of {phase.of(axis)[0].period_px:g} px spans the "
                    f"{spec.pixels(axis)} {axis} alone; no Gray code of periods is needed (unwrap none)"
                )
        return
    if spec.gray is not None:
        raise ValueError(f"gray: phase.unwrap {phase.unwrap} needs no Gray code")
    for axis in phase.axes:
        _check_reach(phase, axis, spec.pixels(axis))


def _check_reach(phase: PhaseShift, axis: Axis, pixels: int) -> None:
    periods = [f.period_px for f in phase.of(axis)]
    where = f"phase.frequencies ({axis})"
    if phase.unwrap in ("hierarchical", "none") and max(periods) < pixels:
        repeats = pixels / max(periods)
        raise ValueError(
            f"{where}: the longest period, {max(periods):g} px, repeats {repeats:.3g} times over the {pixels} "
            f"{axis}; unwrap {phase.unwrap} needs one that spans them (else unwrap gray, heterodyne or micro)"
        )
    if phase.unwrap == "heterodyne":
        if len(set(periods)) != len(periods):
            raise ValueError(f"{where}: periods {periods} repeat; heterodyne needs different periods")
        reach = beat_period(periods)
        if reach < pixels:
            raise ValueError(f"{where}: their beat spans {reach:g} px, less than the {pixels} {axis} to reach")
    if phase.unwrap == "micro":
        margin, first, second = micro_margin(periods, phase.start_deg, pixels)
        if margin < MICRO_MARGIN:
            raise ValueError(
                f"{where}: periods {periods} read {axis} {first} and {second} alike (their single frames differ by "
                f"{margin:.3f} of the fringe amplitude, at least {MICRO_MARGIN} is needed); choose other periods"
            )


def micro_margin(periods: list[float], start_deg: float, pixels: int) -> tuple[float, int, int]:
    """The least distance between the single frames' readings (cosines) of two projector
    coordinates the first period cannot tell apart (a whole number of its periods apart), over
    the projector, and the two coordinates where it is least."""
    first, others = periods[0], np.asarray(periods[1:], dtype=np.float64)
    x = np.arange(pixels, dtype=np.float64)
    start = math.radians(start_deg)
    reading = np.cos(2 * np.pi * x[:, None] / others[None, :] + start)
    best, where = np.inf, (0, 0)
    for k in range(1, math.ceil(pixels / first) + 1):
        partner = x + k * first
        inside = partner < pixels - 0.5
        if not inside.any():
            break
        other = np.cos(2 * np.pi * partner[inside, None] / others[None, :] + start)
        distance = np.sqrt(((reading[inside] - other) ** 2).sum(axis=1))
        at = int(np.argmin(distance))
        if distance[at] < best:
            best, where = float(distance[at]), (int(x[inside][at]), int(np.rint(partner[inside][at])))
    return best, *where


def beat_period(periods: list[float]) -> float:
    """The longest period the heterodyne of 2 or 3 periods resolves (0 where two periods, or the
    two beats of three, are equal)."""
    ordered = sorted(periods)

    def beat(a: float, b: float) -> float:
        return 0.0 if a == b else a * b / abs(b - a)  # equal periods, or equal beats, resolve nothing

    if len(ordered) == 2:
        return beat(*ordered)
    return beat(beat(ordered[0], ordered[1]), beat(ordered[1], ordered[2]))
