"""Calibration settings of a config: the board, simulated session poses, the file reconstruction uses."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, model_validator

from rig.config.common import Strict, Vec3


class BoardConfig(Strict):
    """A checkerboard or ChArUco board. Squares are counted, not inner corners; lengths in mm."""

    kind: Literal["checker", "charuco"] = "checker"
    squares: tuple[int, int] = Field((10, 7), description="squares across (columns) and down (rows)")
    square_mm: float = Field(20.0, gt=1.0, le=500.0)
    marker_mm: float = Field(15.0, gt=0.5, le=500.0, description="ChArUco marker side")
    dictionary: Literal["DICT_4X4_50", "DICT_5X5_100", "DICT_6X6_250"] = "DICT_4X4_50"
    margin_mm: float = Field(10.0, ge=0.0, le=200.0, description="white border around the squares")

    @model_validator(mode="after")
    def _printable(self) -> BoardConfig:
        if min(self.squares) < 3 or max(self.squares) > 100:
            raise ValueError(f"squares {list(self.squares)}: a board needs 3 to 100 squares each way")
        if self.kind == "charuco" and self.marker_mm >= self.square_mm:
            raise ValueError(f"marker_mm {self.marker_mm:g} must be smaller than square_mm {self.square_mm:g}")
        return self

    def orientation_warning(self) -> str | None:
        """Why views of this board may be numbered wrongly, for a checkerboard whose square counts
        are both even or both odd (it looks the same turned half a turn)."""
        cols, rows = self.squares
        if self.kind != "checker" or cols % 2 != rows % 2:
            return None
        return (
            f"the {cols}x{rows}-square checkerboard has {'two even' if cols % 2 == 0 else 'two odd'} counts: it "
            "looks the same turned half a turn, so keep every view within a quarter turn of the first "
            "(or use a board with one count even and one odd, or ChArUco)"
        )


LENS_DISTORTIONS = ("k1", "k1k2", "k1k2_tangential", "full")
LENS_CONSTRAINTS = ("fixed_centre", "fixed_aspect")


class BoardPose(Strict):
    """Where the operator puts the board: its centre and its rotation (x, y, z Euler angles, degrees;
    all zero is flat, face up, columns along world x)."""

    center_mm: Vec3
    rotation_deg: tuple[
        Annotated[float, Field(ge=-180, le=180)],
        Annotated[float, Field(ge=-180, le=180)],
        Annotated[float, Field(ge=-180, le=180)],
    ] = (0.0, 0.0, 0.0)


class CalibrationConfig(Strict):
    board: BoardConfig = BoardConfig()
    views: int = Field(12, ge=3, le=200, description="board poses a simulated calibration session captures")
    poses: list[BoardPose] | None = Field(
        None,
        min_length=3,
        max_length=200,
        description="board poses for the simulated session instead of its own choice; the first defines "
        "the world frame",
    )
    model: str = Field(
        "auto",
        description="lens model of every device: auto (drop what the views do not determine), or a distortion "
        "(k1, k1k2, k1k2_tangential, full) with +fixed_centre and/or +fixed_aspect, e.g. k1k2+fixed_aspect",
    )
    camera_model: str | None = Field(None, description="the cameras' lens model (as model); default: model")
    world: Literal["board", "camera"] = Field(
        "board",
        description="the frame a calibration is written in: board, the first view's board (z = 0 its plane; the "
        "simulated bench's own frame); camera, the first camera's (as other systems write theirs)",
    )
    projector_model: str | None = Field(
        None, description="the projectors' lens model (as model; a DLP's centre is off-axis: not +fixed_centre)"
    )

    file: Path | None = Field(
        None,
        description="calibration.json (or its folder) that reconstruction uses instead of the devices' geometry; "
        "relative paths are relative to the config file",
    )

    @model_validator(mode="after")
    def _known_model(self) -> CalibrationConfig:
        for name in ("model", "camera_model", "projector_model"):
            model = getattr(self, name)
            if model is None:
                continue
            distortion, *constraints = model.split("+")
            if model != "auto" and (
                distortion not in LENS_DISTORTIONS
                or any(c not in LENS_CONSTRAINTS for c in constraints)
                or len(set(constraints)) != len(constraints)
            ):
                raise ValueError(
                    f"{name} {model!r}: auto, or one of {', '.join(LENS_DISTORTIONS)} followed by any of "
                    f"{', '.join('+' + c for c in LENS_CONSTRAINTS)}"
                )
        return self

    @property
    def models(self) -> tuple[str, str]:
        """The cameras' and the projectors' lens models."""
        return self.camera_model or self.model, self.projector_model or self.model
