"""Shared pieces of the config models: the strict base and bounded field types."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

Coord = Annotated[float, Field(ge=-100_000.0, le=100_000.0)]
Vec3 = tuple[Coord, Coord, Coord]
Name = Annotated[str, Field(pattern=r"^[A-Za-z0-9_-]{1,32}$")]
Resolution = tuple[Annotated[int, Field(ge=16, le=16384)], Annotated[int, Field(ge=16, le=16384)]]
Extent = Annotated[float, Field(gt=0.0, le=10_000.0)]
Fraction = Annotated[float, Field(ge=0.0, le=1.0)]
Albedo = Fraction | tuple[Fraction, Fraction, Fraction]  # grey, or linear [red, green, blue]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
