"""A description, in YAML, of what another structured-light system projected, frame by frame, so
that slrig decodes captures it did not make.

```yaml
projector: {resolution: [1024, 768], first_pixel_centre: 0.0}
frames: {files: "graycode_*.png", grey: luminance}
gray:
  axes: [columns, rows]        # in the order their frames come
  code: gray                   # or binary
  order: msb_first             # or lsb_first
  polarity: lit_is_one         # or lit_is_zero
  reference: inverse           # each bit followed by its inverse; or threshold (against white/black)
  layout: interleaved          # bit, inverse, bit, inverse; or grouped: an axis' bits, then its inverses
  white_black: last            # a fully lit and a dark frame: first, last or none
  skipped_low_bits: 0          # finest bits not projected
```

Code i of an axis stands for projector coordinate i * code_step_px + first_pixel_centre in the
calibration's pixels (procam-calibration's convention for its graycode_step).

The description expands into one role per frame (`roles`): the white and black frames, and per
axis each projected bit (0 the most significant) with or without its inverse. The preset
`opencv_graycode` is OpenCV contrib's GrayCodePattern: columns then rows, MSB first, each bit
then its inverse, white and black last.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from pydantic import Field, model_validator

from rig.patterns.diamond import MIRROR_CENTRE
from rig.patterns.spec_phase import Axis, Frequency, Modulation, PhaseShift, Strict, beat_period, check_unwrapping

__all__ = ["Axis", "Frequency", "Modulation", "PhaseShift", "beat_period"]  # the phase block's, from spec_phase


class ProjectorSpace(Strict):
    """The projector's coordinates that the calibration uses."""

    resolution: tuple[int, int] = Field(description="(width, height) in projector pixels")
    first_pixel_centre: float = Field(
        0.0,
        ge=-1.0,
        le=1.0,
        description="the calibration's coordinate of pixel 0's centre: 0 (OpenCV), 0.5, 1 (MATLAB)",
    )
    code_step_px: int = Field(
        1, ge=1, le=64, description="projector pixels per code, as the calibration counts them (procam's graycode_step)"
    )
    diamond_column: Literal["mirror_centre", "sampled"] = Field(
        "mirror_centre",
        description="a diamond DMD's coordinate for a mirror: mirror_centre, half a virtual column right of the "
        "virtual column it shows (the mirror's centre); sampled, that virtual column itself (a system that "
        "samples a virtual-column pattern at each mirror and calibrates in those columns)",
    )
    pixel_geometry: Literal["square", "diamond"] = Field(
        "square",
        description="diamond: a diamond-pixel DMD (LightCrafter 4500) whose mirror columns interleave into twice "
        "as many virtual columns; resolution is then the virtual one (1824x1140) and each frame holds the "
        "mirrors (912x1140)",
    )

    @property
    def column_offset(self) -> float:
        """What a diamond DMD's mirror adds to the virtual column it shows, as its coordinate."""
        centred = self.pixel_geometry == "diamond" and self.diamond_column == "mirror_centre"
        return MIRROR_CENTRE if centred else 0.0

    @model_validator(mode="after")
    def _positive(self) -> ProjectorSpace:
        if not all(1 <= n <= 16384 for n in self.resolution):
            raise ValueError(f"resolution {self.resolution}: each side must be 1 to 16384 pixels")
        if self.pixel_geometry == "diamond" and self.resolution[0] % 2:
            raise ValueError(f"resolution {self.resolution}: a diamond DMD has an even number of virtual columns")
        return self


class FrameFiles(Strict):
    """Which files in the frames folder are the frames, in projection order."""

    files: str | list[str] = Field(
        "*.png",
        description="a glob (matches sorted with numbers in order), or a list in frame order of file names and "
        "globs (e.g. one glob per frequency: [white.png, black.png, 'f16_*.png', 'f18_*.png'])",
    )
    grey: Literal["luminance", "mean", "red", "green", "blue"] = Field("luminance", description="colour to grey")

    @model_validator(mode="after")
    def _inside_the_folder(self) -> FrameFiles:
        entries = [self.files] if isinstance(self.files, str) else self.files
        if not entries:
            raise ValueError("files: an empty list")
        for entry in entries:  # a description names frames in its folder, never beside or above it
            if not entry or "/" in entry or "\\" in entry or entry.startswith(".") or ":" in entry:
                raise ValueError(
                    f"files {entry!r}: a name or glob within the frames folder (no '/', '\\', ':', no leading '.')"
                )
        return self


class GrayCode(Strict):
    axes: tuple[Axis, ...] = Field(("columns",), min_length=1, max_length=2)
    code: Literal["gray", "binary"] = "gray"
    order: Literal["msb_first", "lsb_first"] = "msb_first"
    polarity: Literal["lit_is_one", "lit_is_zero"] = "lit_is_one"
    reference: Literal["inverse", "threshold"] = "inverse"
    layout: Literal["interleaved", "grouped"] = Field("interleaved", description="where the inverse frames are")
    white_black: Literal["first", "last", "none"] = Field("first", description="a fully lit then a dark frame")
    bits: int | None = Field(None, ge=1, le=15, description="bits per axis; default: enough for the resolution")
    skipped_low_bits: int = Field(0, ge=0, le=8, description="the finest bits, not projected")
    threshold: float = Field(
        0.5, gt=0.0, lt=1.0, description="reference threshold: lit above black + this * (white - black)"
    )
    min_contrast: float = Field(0.02, ge=0.0, le=1.0, description="a bit's least |frame - reference|, of full scale")
    black_threshold: float = Field(0.03, ge=0.0, le=1.0, description="least white - black for a lit pixel")

    @model_validator(mode="after")
    def _consistent(self) -> GrayCode:
        if len(set(self.axes)) != len(self.axes):
            raise ValueError(f"axes {list(self.axes)}: an axis twice")
        if self.reference == "threshold" and self.white_black == "none":
            raise ValueError("reference threshold needs the white and black frames (white_black first or last)")
        if self.bits is not None and self.skipped_low_bits >= self.bits:
            raise ValueError(
                f"skipped_low_bits {self.skipped_low_bits}: at least one of the {self.bits} bits is projected"
            )
        return self


@dataclass(frozen=True)
class Role:
    """What one frame shows."""

    shows: Literal["white", "black", "bit", "phase"]
    axis: Axis | None = None
    bit: int = 0  # a bit: 0 the most significant; a phase frame: its frequency
    inverse: bool = False
    step: int = 0  # a phase frame's step n
    carrier: int = 0  # modulated phase shifting: the carrier's shift m


class PatternSpec(Strict):
    projector: ProjectorSpace
    frames: FrameFiles = FrameFiles()
    gray: GrayCode | None = Field(None, description="a Gray or binary code; with phase, of the period index")
    phase: PhaseShift | None = None

    @property
    def axes(self) -> tuple[Axis, ...]:
        """The coded axes, in the order their frames come."""
        return self.phase.axes if self.phase is not None else self.code.axes

    @property
    def code(self) -> GrayCode:
        """The Gray code block (present wherever a bit role is)."""
        assert self.gray is not None
        return self.gray

    def bits(self, axis: Axis) -> int:
        """Bits of `axis`' code, projected or not."""
        if self.code.bits is not None:
            return self.code.bits
        return max(1, math.ceil(math.log2(self.extent(axis))))

    def pixels(self, axis: Axis) -> int:
        return self.projector.resolution[0 if axis == "columns" else 1]

    def extent(self, axis: Axis) -> int:
        """Codes along `axis`: the projector's pixels over the pixels per code (with phase, per
        period or half period)."""
        return math.ceil(self.pixels(axis) / self.code_step(axis))

    def code_step(self, axis: Axis) -> float:
        """Projector pixels per code of the gray block."""
        if self.phase is None:
            return self.projector.code_step_px
        period = self.phase.of(axis)[0].period_px
        return period / 2 if self.phase.gray_unit == "half_period" else period

    def roles(self) -> list[Role]:
        """One role per frame, in the order the frames come: per axis its phase frames (by frequency),
        then its Gray code's."""
        coded: list[Role] = []
        for axis in self.axes:
            if self.phase is not None:
                carriers = range(self.phase.modulation.steps if self.phase.modulation is not None else 1)
                for f, frequency in enumerate(self.phase.of(axis)):
                    steps = range(frequency.steps)
                    coded += [Role("phase", axis, f, step=n, carrier=m) for n in steps for m in carriers]
            if self.gray is None:
                continue
            gray = self.gray
            projected = list(range(self.bits(axis) - gray.skipped_low_bits))
            if gray.order == "lsb_first":
                projected.reverse()
            plain = [Role("bit", axis, b) for b in projected]
            if gray.reference == "threshold":
                coded += plain
            elif gray.layout == "interleaved":
                coded += [r for b in projected for r in (Role("bit", axis, b), Role("bit", axis, b, True))]
            else:
                coded += plain + [Role("bit", axis, b, True) for b in projected]
        references = [Role("white"), Role("black")]
        where = self.gray.white_black if self.gray is not None else self.phase.white_black  # type: ignore[union-attr]
        if where == "first":
            return references + coded
        if where == "last":
            return coded + references
        return coded

    def frame_breakdown(self) -> str:
        """Where a description's frame count comes from, to print beside it: ' (columns: 24 phase
        (16 px x 8 steps, ...), 10 Gray; white and black 2)'."""
        roles, parts = self.roles(), []
        for axis in self.axes:
            pieces = []
            if self.phase is not None:
                carriers = f" x {self.phase.modulation.steps} carrier shifts" if self.phase.modulation else ""
                each = ", ".join(f"{f.period_px:g} px x {f.steps}" for f in self.phase.of(axis))
                count = sum(1 for r in roles if r.shows == "phase" and r.axis == axis)
                pieces.append(f"{count} phase ({each}{carriers})")
            bits = sum(1 for r in roles if r.shows == "bit" and r.axis == axis)
            if bits:
                pieces.append(f"{bits} Gray")
            parts.append(f"{axis}: {', '.join(pieces)}")
        references = sum(1 for r in roles if r.shows in ("white", "black"))
        if references:
            parts.append(f"white and black {references}")
        return f" ({'; '.join(parts)})"

    @model_validator(mode="after")
    def _bits_fit(self) -> PatternSpec:
        if self.gray is None and self.phase is None:
            raise ValueError("a description needs a gray or a phase block (or both: phase unwrapped by gray)")
        if self.phase is not None:
            check_unwrapping(self)
        if self.gray is None:
            return self
        for axis in self.gray.axes:
            if 2 ** self.bits(axis) < self.extent(axis):
                raise ValueError(f"gray.bits {self.bits(axis)}: too few for {self.extent(axis)} {axis}")
        return self


def opencv_graycode(width: int, height: int, files: str = "*.png") -> PatternSpec:
    """OpenCV contrib's structured_light.GrayCodePattern for a `width` x `height` projector."""
    return PatternSpec(
        projector=ProjectorSpace(resolution=(width, height)),
        frames=FrameFiles(files=files),
        gray=GrayCode(axes=("columns", "rows"), white_black="last"),
    )
