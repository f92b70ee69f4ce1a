"""`gray`: binary Gray code with inverse patterns, columns and optionally rows."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from rig.patterns.base import Codec, CodecParams, Correspondence
from rig.patterns.graycode import bit_count, decode_gray, gray_planes, planes_with_inverses
from rig.patterns.registry import register

Directions = Literal["columns", "rows", "both"]


class GrayParams(CodecParams):
    directions: Directions = Field("columns", description="which projector coordinates to code")
    white_threshold: float = Field(
        0.02,
        ge=0.0,
        le=1.0,
        description="minimum |pattern - inverse| of every bit but the weakest (fraction of full scale)",
    )


def _axes(directions: str) -> list[str]:
    return {"columns": ["u"], "rows": ["v"], "both": ["u", "v"]}[directions]


@register
class GrayCodec(Codec):
    name = "gray"
    Params = GrayParams
    params: GrayParams

    def _extent(self, axis: str) -> int:
        return self.width if axis == "u" else self.height

    def _coded_patterns(self) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for axis in _axes(self.params.directions):
            n = self._extent(axis)
            index = np.arange(n)
            planes = gray_planes(index, bit_count(n))
            for img in planes_with_inverses(planes):
                out.append(self._stretch(img, axis))
        return out

    def _stretch(self, line: np.ndarray, axis: str) -> np.ndarray:
        if axis == "u":
            return np.ascontiguousarray(np.broadcast_to(line, (self.height, self.width)))
        return np.ascontiguousarray(np.broadcast_to(line[:, None], (self.height, self.width)))

    def _decode(self, frames, white, black, lit, texture) -> Correspondence:  # type: ignore[no-untyped-def]
        coords: dict[str, np.ndarray] = {}
        valid = lit.copy()
        quality = white - black
        counts = {"lit": int(lit.sum())}
        offset = 0
        for axis in _axes(self.params.directions):
            n = self._extent(axis)
            bits = bit_count(n)
            value, strength = decode_gray(frames[offset : offset + 2 * bits], bits)
            offset += 2 * bits
            ok = (strength >= self.params.white_threshold) & (value < n)
            counts[f"weak_bits_{axis}"] = int((lit & ~ok).sum())
            valid &= ok
            coords[axis] = value.astype(np.float32)
        for axis in coords:
            coords[axis][~valid] = np.nan
        counts["decoded"] = int(valid.sum())
        return Correspondence(
            valid=valid, quality=quality, texture=texture, u=coords.get("u"), v=coords.get("v"), counts=counts
        )
