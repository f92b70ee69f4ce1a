"""Phase-shift frames another system captured (the `phase` block of a pattern description), decoded
into slrig's Correspondence, and the projector images such a description stands for.

Each frequency's N frames give a wrapped phase, a fraction of its period: frame n shows
0.5 + 0.5 cos(2 pi x / P + start + s 2 pi n / N), so with d_n = s 2 pi n / N,
sum I_n cos d_n = (N/2) B cos(theta) and sum I_n sin d_n = -(N/2) B sin(theta), theta = 2 pi x / P + start.

Unwrapping, as the description says:
- gray: a Gray code of the period index k = floor(x / P), x = (k + fraction) P; or of the half-period
  index (gray_unit half_period, slrig's own phase codec), read as gray_unwrapped says.
- heterodyne: two periods P1 < P2 beat with period P1 P2 / (P2 - P1) (three: the beat of the two
  beats), long enough to span the projector; each beat's coordinate unwraps the next finer phase.
- hierarchical: the longest period spans the projector (a single-period cue) and unwraps the
  next shorter, down to the shortest.

With a Gray code of periods, a pixel whose period count comes out one off (the code's edge read a pixel away
from the phase's wrap) differs from its 5x5 neighbourhood's median by about a period: that jump is
taken back. With several frequencies, every frequency unwrapped at the finest one's coordinate
gives an estimate, and their mean weighted by 1 / P^2 (a phase's noise in pixels grows with its
period) is the coordinate.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import cv2
import numpy as np

from rig.patterns.correspondence import Correspondence, NormalizedFrames
from rig.patterns.lines import LineCodec, stretch
from rig.patterns.micro_phase import micro_unwrapped
from rig.patterns.spec import Axis, PatternSpec, Role

GrayReader = Callable[[Axis, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
Wrapped = tuple[np.ndarray, float]  # (fraction of the period in [0, 1), period in pixels)
MIN_NEIGHBOURS = 9  # valid pixels of a 5x5 neighbourhood that may take a period jump back
MAX_DOUBT = 0.3  # of a period: how far a coarser coordinate may miss the finer phase's periods


def decode_phase(
    frames: NormalizedFrames, spec: PatternSpec, index: dict[Role, int], raw: list[np.ndarray], read_gray: GrayReader
) -> Correspondence:
    """Projector coordinates from phase frames; `read_gray` reads an axis' Gray code (value, strength)
    between the white and black references, for `unwrap: gray`."""
    phase = spec.phase
    assert phase is not None
    full_scale = 65535 if raw[0].dtype == np.uint16 else 255
    coords: dict[str, np.ndarray] = {}
    valid: np.ndarray | None = None
    readable: np.ndarray | None = None
    quality: np.ndarray | None = None
    texture: np.ndarray | None = None
    counts: dict[str, int] = {}
    for axis in spec.axes:
        frequencies = phase.of(axis)
        shifted = [(f, q) for f, q in enumerate(frequencies) if q.steps >= 3]  # micro: the first alone
        measured = [_wrapped(frames, index, axis, f, q.steps, spec) for f, q in shifted]
        wrapped = [(m[0], q.period_px) for m, (_, q) in zip(measured, shifted, strict=True)]
        finest = min(range(len(wrapped)), key=lambda f: wrapped[f][1])
        _, offset, modulation = measured[finest]  # the finest frequency's mean and amplitude
        ok = modulation >= phase.min_modulation
        counts[f"low_modulation_{axis}"] = int((~ok).sum())
        if Role("white") in index:  # unlit where white and black differ too little, as for a code
            least = spec.gray.black_threshold if spec.gray is not None else phase.min_modulation
            ok &= frames[index[Role("white")]] - frames[index[Role("black")]] >= least
        readable = ok.copy() if readable is None else readable & ok  # lit enough to read, before unwrapping
        x, ok = _unwrapped(frames, spec, index, axis, measured, wrapped, offset, modulation, ok, read_gray, counts)
        counts[f"beyond_projector_{axis}"] = int((ok & ~((x > -0.5) & (x < spec.pixels(axis) - 0.5))).sum())
        ok &= (x > -0.5) & (x < spec.pixels(axis) - 0.5)
        coords["u" if axis == "columns" else "v"] = (x + np.float32(spec.projector.first_pixel_centre)).astype(
            np.float32
        )
        valid = ok if valid is None else valid & ok
        quality = modulation if quality is None else np.minimum(quality, modulation)
        if texture is None:
            lit = index.get(Role("white"))
            peak = frames[lit] if lit is not None else offset + modulation
            texture = np.clip(peak * full_scale, 0, full_scale).astype(raw[0].dtype)
    assert valid is not None and quality is not None and texture is not None
    assert readable is not None
    counts["lit"] = int(readable.sum())
    return LineCodec.correspondence(coords, valid, quality, texture, counts)


def _unwrapped(
    frames: NormalizedFrames,
    spec: PatternSpec,
    index: dict[Role, int],
    axis: Axis,
    measured: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
    wrapped: list[Wrapped],
    offset: np.ndarray,
    modulation: np.ndarray,
    ok: np.ndarray,
    read_gray: GrayReader,
    counts: dict[str, int],
) -> tuple[np.ndarray, np.ndarray]:
    """The axis' coordinate as the description's unwrapping reads it, and the pixels still valid
    (counting those it drops in `counts`)."""
    phase = spec.phase
    assert phase is not None
    frequencies = phase.of(axis)
    if phase.unwrap == "gray":
        white, black = _references(frames, index, offset, modulation)
        value, strength = read_gray(axis, white, black)
        x = gray_unwrapped(value, wrapped[0], phase.gray_unit == "half_period", ok)
        return x, ok & (strength >= spec.code.min_contrast)
    if phase.unwrap == "none":
        counts[f"phase_noise_millipx_{axis}"] = _noise_millipx(frames, index, axis, spec, measured[0], ok)
        return spanning(wrapped[0], spec.pixels(axis)), ok
    if phase.unwrap == "micro":
        singles = [_frame(frames, index, Role("phase", axis, f), spec) for f in range(1, len(frequencies))]
        periods = [q.period_px for q in frequencies]
        x, clear = micro_unwrapped(
            wrapped[0][0], offset, modulation, singles, periods, phase.start_deg, spec.pixels(axis)
        )
        counts[f"unwrap_doubtful_{axis}"] = int((ok & ~clear).sum())
        return x, ok & clear
    unwrapping = heterodyne if phase.unwrap == "heterodyne" else hierarchical
    x, doubt = unwrapping(wrapped, spec.pixels(axis))
    counts[f"unwrap_doubtful_{axis}"] = int((ok & (doubt > MAX_DOUBT)).sum())
    return combined(x, wrapped), ok & (doubt <= MAX_DOUBT)


def _wrapped(
    frames: NormalizedFrames, index: dict[Role, int], axis: Axis, f: int, steps: int, spec: PatternSpec
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fraction of the period, the mean and the amplitude of one frequency's frames."""
    phase = spec.phase
    assert phase is not None
    sign = 1.0 if phase.shift == "plus" else -1.0
    s = c = total = None
    for n in range(steps):
        frame = _frame(frames, index, Role("phase", axis, f, step=n), spec)
        delta = sign * 2 * np.pi * n / steps
        s = frame * np.float32(np.sin(delta)) if s is None else s + frame * np.float32(np.sin(delta))
        c = frame * np.float32(np.cos(delta)) if c is None else c + frame * np.float32(np.cos(delta))
        total = frame.copy() if total is None else total + frame
    assert s is not None and c is not None and total is not None
    theta = np.arctan2(-s, c) - np.float32(np.radians(phase.start_deg))
    fraction = np.mod(theta / np.float32(2 * np.pi), np.float32(1.0)).astype(np.float32)
    return fraction, total / np.float32(steps), np.float32(2.0 / steps) * np.sqrt(s * s + c * c)


def _frame(frames: NormalizedFrames, index: dict[Role, int], role: Role, spec: PatternSpec) -> np.ndarray:
    """A phase frame as read: as captured, or, for modulated phase shifting, twice the amplitude
    of its carrier over the carrier's M shifts: the light that came straight from the projector
    (light scattered within the scene is smooth across the carrier and drops out)."""
    phase = spec.phase
    assert phase is not None
    if phase.modulation is None:
        return frames[index[role]]
    steps = phase.modulation.steps
    s = c = None
    for m in range(steps):
        frame = frames[index[dataclasses.replace(role, carrier=m)]]
        angle = 2 * np.pi * m / steps
        s = frame * np.float32(np.sin(angle)) if s is None else s + frame * np.float32(np.sin(angle))
        c = frame * np.float32(np.cos(angle)) if c is None else c + frame * np.float32(np.cos(angle))
    assert s is not None and c is not None
    return np.float32(4.0 / steps) * np.sqrt(s * s + c * c)


def _noise_millipx(
    frames: NormalizedFrames,
    index: dict[Role, int],
    axis: Axis,
    spec: PatternSpec,
    measured: tuple[np.ndarray, np.ndarray, np.ndarray],
    valid: np.ndarray,
) -> int:
    """The median coordinate noise of a phase read without unwrapping, in thousandths of a
    projector pixel: the frames' residual from their fitted sinusoid (N - 3 degrees of freedom),
    as phase noise sqrt(2 / N) sigma / B, times P / 2 pi. -1 with 3 steps (no residual)."""
    phase = spec.phase
    assert phase is not None
    frequency = phase.of(axis)[0]
    steps = frequency.steps
    if steps <= 3 or not valid.any():
        return -1
    fraction, offset, amplitude = measured
    sign = 1.0 if phase.shift == "plus" else -1.0
    theta = fraction * np.float32(2 * np.pi) + np.float32(np.radians(phase.start_deg))
    squares = np.zeros_like(offset)
    for n in range(steps):
        delta = np.float32(sign * 2 * np.pi * n / steps)
        fitted = offset + amplitude * np.cos(theta + delta)
        squares += (_frame(frames, index, Role("phase", axis, 0, step=n), spec) - fitted) ** 2
    sigma = np.sqrt(squares / np.float32(steps - 3))
    noise = sigma * np.float32(math.sqrt(2.0 / steps)) / np.maximum(amplitude, np.float32(1e-6))
    return round(float(np.median(noise[valid])) * frequency.period_px / (2 * math.pi) * 1000)


def _references(
    frames: NormalizedFrames, index: dict[Role, int], offset: np.ndarray, modulation: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """White and black: the frames where the description has them, else the fringes' peak and trough."""
    if Role("white") in index:
        return frames[index[Role("white")]], frames[index[Role("black")]]
    return offset + modulation, offset - modulation


def unwrap(coarse: np.ndarray, fine: Wrapped) -> np.ndarray:
    """The fine phase's coordinate, its period count taken from a coarser coordinate of the same point."""
    return _unwrap(coarse, fine)[0]


def _unwrap(coarse: np.ndarray, fine: Wrapped) -> tuple[np.ndarray, np.ndarray]:
    """The fine coordinate and the doubt: how far (in periods) the coarse one missed a whole count."""
    fraction, period = fine
    periods = coarse / np.float32(period) - fraction
    count = np.rint(periods)
    return ((count + fraction) * np.float32(period)).astype(np.float32), np.abs(periods - count)


def beat(a: Wrapped, b: Wrapped) -> Wrapped:
    """The phase two periods make together: their difference, with period Pa Pb / |Pb - Pa|."""
    (fa, pa), (fb, pb) = sorted([a, b], key=lambda w: w[1])
    return np.mod(fa - fb, np.float32(1.0)).astype(np.float32), pa * pb / (pb - pa)


def spanning(top: Wrapped, pixels: int) -> np.ndarray:
    """The coordinate of a phase whose one period spans the projector's `pixels`: a value in the gap
    between the projector's end and the period's (or within a quarter pixel of the period's end,
    where the two meet) is the projector's start, read across the wrap."""
    fraction, period = top
    x = fraction * np.float32(period)
    fold = (pixels - 0.5 + period) / 2
    return np.where(x > fold, x - np.float32(period), x).astype(np.float32)


def heterodyne(wrapped: list[Wrapped], pixels: int) -> tuple[np.ndarray, np.ndarray]:
    """The finest coordinate through the beats, and the largest doubt on the way."""
    ordered = sorted(wrapped, key=lambda w: w[1])
    beats = [beat(ordered[i], ordered[i + 1]) for i in range(len(ordered) - 1)]
    doubt = np.zeros_like(ordered[0][0])
    if len(beats) == 2:  # three frequencies: the beat of the beats spans the projector
        x, doubt = _unwrap(spanning(beat(*beats), pixels), min(beats, key=lambda w: w[1]))
    else:
        x = spanning(beats[0], pixels)
    x, last = _unwrap(x, ordered[0])
    return x, np.maximum(doubt, last)


def hierarchical(wrapped: list[Wrapped], pixels: int) -> tuple[np.ndarray, np.ndarray]:
    """The finest coordinate from the longest period down, and the largest doubt on the way."""
    ordered = sorted(wrapped, key=lambda w: w[1], reverse=True)
    x = spanning(ordered[0], pixels)
    doubt = np.zeros_like(x)
    for fine in ordered[1:]:
        x, step = _unwrap(x, fine)
        doubt = np.maximum(doubt, step)
    return x, doubt


def combined(x: np.ndarray, wrapped: list[Wrapped]) -> np.ndarray:
    """Every frequency unwrapped at `x`, averaged with weights 1 / P^2."""
    weights = [1.0 / period**2 for _, period in wrapped]
    total = sum(np.float32(w) * unwrap(x, w_) for w, w_ in zip(weights, wrapped, strict=True))
    return (total / np.float32(sum(weights))).astype(np.float32)


def gray_unwrapped(code: np.ndarray, wrapped: Wrapped, half_periods: bool, valid: np.ndarray) -> np.ndarray:
    """The coordinate from a Gray code's count. Of half periods h: two counts, k1 = h >> 1 with its
    edges at the phase's wraps and k2 = (h + 1) >> 1 with its edges mid-period; near a wrap (within a
    quarter period) k2 is read, elsewhere k1, so neither is read near its own edges. Of periods: the
    count as read, its jumps taken back by the median."""
    fraction, period = wrapped
    if not half_periods:
        return correct_period_jumps((code.astype(np.float32) + fraction) * np.float32(period), period, valid)
    k1, k2 = code >> 1, (code + 1) >> 1
    count = np.where(fraction < 0.25, k2, np.where(fraction > 0.75, k2 - 1, k1))
    return ((count + fraction) * np.float32(period)).astype(np.float32)


def correct_period_jumps(x: np.ndarray, period: float, valid: np.ndarray) -> np.ndarray:
    """Take back whole periods where a pixel differs from the median of its 5x5 neighbourhood's
    valid pixels by more than half a period (a Gray code edge read one pixel off the phase's wrap).
    The median is taken fast twice, the invalid pixels counted once far below and once far above;
    where the two agree on the jump that is the answer, elsewhere (near invalid pixels) the valid
    neighbours' own median decides, and a pixel with fewer than MIN_NEIGHBOURS of them is left."""
    far = np.float32(1e6)
    jumps = [
        np.rint((cv2.medianBlur(np.where(valid, x, fill).astype(np.float32), 5) - x) / np.float32(period))
        for fill in (-far, far)
    ]
    jump = np.where(jumps[0] == jumps[1], jumps[0], 0)
    rows, cols = np.nonzero(valid & (jumps[0] != jumps[1]))
    if len(rows):
        padded_x = np.pad(x, 2)
        padded_valid = np.pad(valid, 2)
        offsets = np.arange(5)
        window_rows = rows[:, None, None] + offsets[None, :, None]
        window_cols = cols[:, None, None] + offsets[None, None, :]
        values = np.where(padded_valid[window_rows, window_cols], padded_x[window_rows, window_cols], np.nan)
        values = values.reshape(len(rows), 25)
        enough = np.sum(~np.isnan(values), axis=1) >= MIN_NEIGHBOURS
        median = np.nanmedian(np.where(enough[:, None], values, 0.0), axis=1)
        jump[rows, cols] = np.where(enough, np.rint((median - x[rows, cols]) / np.float32(period)), 0)
    return np.where(valid, x + jump * np.float32(period), x).astype(np.float32)


def phase_pattern(spec: PatternSpec, role: Role) -> np.ndarray:
    """The projector image (uint8) of one phase frame (with modulated phase shifting, times its
    carrier along the other axis)."""
    phase = spec.phase
    assert phase is not None and role.axis is not None
    width, height = spec.projector.resolution
    frequency = phase.of(role.axis)[role.bit]
    x = np.arange(spec.pixels(role.axis), dtype=np.float64)
    if role.axis == "columns":
        x += spec.projector.column_offset  # a diamond's mirror shows the fringe at its coordinate
    sign = 1.0 if phase.shift == "plus" else -1.0
    angle = (
        2 * np.pi * x / frequency.period_px
        + np.radians(phase.start_deg)
        + sign * 2 * np.pi * role.step / frequency.steps
    )
    fringe = 0.5 + 0.5 * np.cos(angle)
    if phase.modulation is None:
        return stretch(np.rint(fringe * 255).astype(np.uint8), "u" if role.axis == "columns" else "v", width, height)
    across = "rows" if role.axis == "columns" else "columns"
    y = np.arange(spec.pixels(across), dtype=np.float64)
    carrier = 0.5 + 0.5 * np.cos(2 * np.pi * (y / phase.modulation.period_px + role.carrier / phase.modulation.steps))
    image = carrier[:, None] * fringe[None, :] if role.axis == "columns" else fringe[:, None] * carrier[None, :]
    return np.rint(image * 255).astype(np.uint8)
