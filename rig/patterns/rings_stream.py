"""The ring codec's decoder fed frame by frame (rig.patterns.rings.RingsCodec.stream).

Each part of the decode is done when its frames have come, with the batch decoder's own steps
(RingsCodec.locate and .correspondence), so both give the same samples bit for bit:
- the edge pair: the edge pattern's sign changes (Crossings.candidates), the costly search;
- each ring index pair: read in integer counts (GrayBits);
- the last coarse angle step: the ring points among the sign changes, their coarse angle, the
  coarse bands of every pixel;
- each fine angle step: read at the ring points' pixels only.
After the last frame only the fine angle at the ring points and the samples remain.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from rig.patterns.correspondence import Correspondence, NormalizedFrames, least_counts
from rig.patterns.crossings import Crossings, LocatedRings
from rig.patterns.fringes import PointSums, RunningSums
from rig.patterns.stream import DenseBase, FrameStream, GrayBits


class RingsCodec(Protocol):
    """What the stream needs of the ring codec (rig.patterns.rings.RingsCodec): the same steps its
    batch decode takes, so that both give the same samples; this module does not import the codec's."""

    name: str
    params: Any
    frame_count: int
    drops_outshone: bool
    deblur_px: float
    fine_periods: np.ndarray | None

    def decode(self, frames: list[np.ndarray], full_scale: int) -> Correspondence: ...

    def stream(self, full_scale: int) -> FrameStream: ...

    def _zone_bits(self) -> int: ...

    def locate(self, *args: Any) -> LocatedRings: ...

    def correspondence(self, *args: Any) -> Correspondence: ...


class RingsStream(FrameStream):
    codec: RingsCodec

    def __init__(self, codec: RingsCodec, full_scale: int) -> None:
        super().__init__(codec, full_scale)
        p = codec.params
        self._base = DenseBase(codec, full_scale)
        bits = codec._zone_bits()
        self._coarse_from = 2 + 2 * bits  # coded frames before the coarse angle's first step
        self._fine_from = self._coarse_from + p.angle_steps
        self._min_zone_counts = least_counts(p.min_edge_contrast * 0.5, full_scale)
        self._held: list[np.ndarray] = []  # the edge pattern and its inverse
        self._coarse: RunningSums | None = RunningSums(p.angle_steps)  # the coarse angle's steps, summed as they arrive
        self._edge: np.ndarray | None = None
        self._candidates: Crossings | None = None
        self._reader: GrayBits | None = GrayBits(bits)
        self._found: LocatedRings | None = None
        self._fine: PointSums | None = None

    def _consume(self, index: int, frame: np.ndarray) -> None:
        image = self._base.coded_frame(index, frame)
        if image is None:
            return
        coded = index - 2
        if coded < 2:
            self._held.append(image)
            if coded == 1:
                self._edge_pair()
        elif coded < self._coarse_from:
            assert self._reader is not None
            self._reader.take(image)
        elif coded < self._fine_from:
            assert self._coarse is not None
            self._coarse.add(NormalizedFrames([image], self.full_scale)[0])
            if coded == self._fine_from - 1:
                self._locate()
        else:
            assert self._fine is not None
            self._fine.add(self._fine.values_in(image, self.full_scale))

    def _edge_pair(self) -> None:
        normalized = NormalizedFrames(self._held, self.full_scale)
        self._edge = normalized[0] - normalized[1]
        self._candidates = Crossings.candidates(self._edge, self.codec.params.min_edge_contrast)
        self._held = []

    def _locate(self) -> None:
        base, reader, p, sums = self._base, self._reader, self.codec.params, self._coarse
        assert base.lit is not None and reader is not None and self._edge is not None and self._candidates is not None
        assert sums is not None
        coarse = (sums.s, sums.c)
        zone = reader.value().astype(np.int32)  # as the batch decoder reads it
        strong = reader.strength() >= self._min_zone_counts
        self._found = self.codec.locate(self._candidates, self._edge, base.contrast(), zone, strong, base.lit, coarse)
        self._coarse, self._edge, self._candidates, self._reader = None, None, None, None
        if self.codec.fine_periods is not None:
            self._fine = PointSums(self._found.ends, p.tangential_steps)

    def _finish(self) -> Correspondence:
        base, found = self._base, self._found
        assert found is not None and base.lit is not None and base.texture is not None
        return self.codec.correspondence(found, self._fine, base.contrast(), base.lit, base.texture)
