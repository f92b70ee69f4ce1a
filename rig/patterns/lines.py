"""Shared parts of codecs whose patterns are stripes along projector columns and/or rows."""

from __future__ import annotations

import abc
from collections.abc import Iterator
from typing import Literal

import numpy as np
from pydantic import Field

from rig.patterns.base import Codec, CodecParams
from rig.patterns.correspondence import Correspondence

Directions = Literal["columns", "rows", "both"]


def stretch(line: np.ndarray, axis: str, width: int, height: int) -> np.ndarray:
    """A 1-D profile along `axis` ("u": across the columns, "v": down the rows) as a width x height image."""
    if axis == "u":
        return np.ascontiguousarray(np.broadcast_to(line, (height, width)))
    return np.ascontiguousarray(np.broadcast_to(line[:, None], (height, width)))


class LineParams(CodecParams):
    directions: Directions = Field("columns", description="which projector coordinates to code")
    white_threshold: float = Field(
        0.02, ge=0.0, le=1.0, description="minimum |pattern - inverse| of the Gray-code bits (fraction of full scale)"
    )


class LineCodec(Codec):
    """Patterns that vary along one projector axis: `u` (columns) and/or `v` (rows)."""

    params: LineParams

    def axes(self) -> list[str]:
        return {"columns": ["u"], "rows": ["v"], "both": ["u", "v"]}[self.params.directions]

    def coded_axes(self) -> str:
        return "".join(self.axes())

    def extent(self, axis: str) -> int:
        return self.width if axis == "u" else self.height

    def stretch(self, line: np.ndarray, axis: str) -> np.ndarray:
        """A 1-D profile along `axis` as a full projector image."""
        return stretch(line, axis, self.width, self.height)

    @abc.abstractmethod
    def _coded_lines(self) -> list[tuple[np.ndarray, str]]:
        """Each coded pattern as its 1-D profile (uint8) and the axis it runs along."""

    def _coded_iter(self) -> Iterator[np.ndarray]:
        for line, axis in self._coded_lines():  # a profile is a few hundred bytes, its image 0.8 MB
            yield self.stretch(line, axis)

    @staticmethod
    def correspondence(
        coords: dict[str, np.ndarray],
        valid: np.ndarray,
        quality: np.ndarray,
        texture: np.ndarray,
        counts: dict[str, int],
    ) -> Correspondence:
        for axis in coords:
            coords[axis][~valid] = np.nan
        counts["decoded"] = int(valid.sum())
        return Correspondence(
            valid=valid, quality=quality, texture=texture, u=coords.get("u"), v=coords.get("v"), counts=counts
        )
