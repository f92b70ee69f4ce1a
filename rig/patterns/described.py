"""Decode frames another system captured, as a pattern description (rig.patterns.spec) says they
were projected, into slrig's Correspondence."""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np

from rig.errors import DecodeError
from rig.patterns.correspondence import Correspondence, NormalizedFrames
from rig.patterns.described_phase import decode_phase, phase_pattern
from rig.patterns.diamond import mirror_image
from rig.patterns.graycode import read_bits
from rig.patterns.lines import LineCodec, stretch
from rig.patterns.spec import Axis, PatternSpec, Role


def decode_described(frames: Sequence[np.ndarray], spec: PatternSpec, full_scale: int) -> Correspondence:
    """Per camera pixel, the projector column and/or row its frames spell out (NaN where a pixel is
    unlit, a bit too weak to read, or the code beyond the projector). `frames` may be arriving
    (rig.store.frames.ArrivingFrames, which checks each frame's size as it comes): they are used in
    order where the description allows."""
    roles = spec.roles()
    if len(frames) != len(roles):
        raise DecodeError(
            f"the pattern description has {len(roles)} frames{spec.frame_breakdown()}, {len(frames)} were given"
        )
    if isinstance(frames, list) and len({f.shape[:2] for f in frames}) != 1:
        raise DecodeError(f"frames differ in size: {sorted({f.shape[:2] for f in frames})}")
    normalized = NormalizedFrames(frames, full_scale)
    index = {role: i for i, role in enumerate(roles)}
    if spec.phase is not None:

        def read_gray(axis: Axis, white: np.ndarray, black: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return _read_axis(normalized, spec, axis, index, white, black)

        return decode_phase(normalized, spec, index, frames, read_gray)
    white, black, texture = _references(normalized, roles, index, frames)
    gray = spec.code
    lit = (white - black) >= gray.black_threshold
    valid = lit.copy()
    coords: dict[str, np.ndarray] = {}
    counts = {"lit": int(lit.sum())}
    for axis in gray.axes:
        value, strength = _read_axis(normalized, spec, axis, index, white, black)
        skipped = gray.skipped_low_bits
        middle = np.float32((2**skipped - 1) / 2.0)  # of the span the skipped finest bits leave open
        position = (value << skipped).astype(np.float32) + middle
        ok = (strength >= gray.min_contrast) & (position <= spec.extent(axis) - 1)
        counts[f"weak_bits_{'u' if axis == 'columns' else 'v'}"] = int((lit & ~ok).sum())
        valid &= ok
        step, centre = spec.projector.code_step_px, spec.projector.first_pixel_centre
        if axis == "columns":
            centre += spec.projector.column_offset  # a diamond's mirror: centred right of the column it shows
        coords["u" if axis == "columns" else "v"] = position * np.float32(step) + np.float32(centre)
    return LineCodec.correspondence(coords, valid, white - black, texture, counts)


def _references(
    frames: NormalizedFrames, roles: list[Role], index: dict[Role, int], raw: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """White, black (normalised) and the texture (as captured). Without white and black frames: the
    brighter and darker of the first bit and its inverse, which light every pixel once."""
    if Role("white") in index:
        at = index[Role("white")]
        return frames[at], frames[index[Role("black")]], raw[at]
    first = roles[0]
    pair = frames[index[first]], frames[index[Role("bit", first.axis, first.bit, True)]]
    brighter = np.maximum(*pair)
    full_scale = 65535 if raw[0].dtype == np.uint16 else 255
    texture = np.clip(brighter * full_scale, 0, full_scale).astype(raw[0].dtype)
    return brighter, np.minimum(*pair), texture


def _read_axis(
    frames: NormalizedFrames,
    spec: PatternSpec,
    axis: Axis,
    index: dict[Role, int],
    white: np.ndarray,
    black: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The binary value of the projected bits and the second weakest bit's strength: at a stripe
    edge of a Gray code only one bit changes, so one weak bit is no reason to reject a pixel."""
    gray = spec.code
    threshold = black + np.float32(gray.threshold) * (white - black)
    sign = np.float32(1.0 if gray.polarity == "lit_is_one" else -1.0)

    def differences() -> Iterator[np.ndarray]:
        for bit in range(spec.bits(axis) - gray.skipped_low_bits):
            frame = frames[index[Role("bit", axis, bit)]]
            if gray.reference == "inverse":
                yield sign * (frame - frames[index[Role("bit", axis, bit, True)]])
            else:
                yield sign * 2.0 * (frame - threshold)  # on the scale of frame - inverse

    return read_bits(differences(), gray=gray.code == "gray")


def described_patterns(spec: PatternSpec) -> list[np.ndarray]:
    """The projector images (uint8) the description says were shown, in frame order: what the
    simulated bench projects to make captures in another system's convention (for a diamond DMD,
    the mirrors' images)."""
    virtual = _virtual_patterns(spec)
    return [mirror_image(v) for v in virtual] if spec.projector.pixel_geometry == "diamond" else virtual


def _virtual_patterns(spec: PatternSpec) -> list[np.ndarray]:
    width, height = spec.projector.resolution
    out = []
    for role in spec.roles():
        if role.shows == "phase":
            out.append(phase_pattern(spec, role))
            continue
        if role.shows != "bit":
            out.append(np.full((height, width), 255 if role.shows == "white" else 0, np.uint8))
            continue
        assert role.axis is not None
        size = width if role.axis == "columns" else height
        index = (np.arange(size) // spec.code_step(role.axis)).astype(np.int64)
        code = index ^ (index >> 1) if spec.code.code == "gray" else index
        lit = ((code >> (spec.bits(role.axis) - 1 - role.bit)) & 1).astype(bool)
        lit ^= role.inverse ^ (spec.code.polarity == "lit_is_zero")
        out.append(stretch(lit.astype(np.uint8) * 255, "u" if role.axis == "columns" else "v", width, height))
    return out
