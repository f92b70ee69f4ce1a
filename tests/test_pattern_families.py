"""Every phase family a description can name, projected as it says and seen by a camera that
looks at the projector through a smooth, sub-pixel warp (bilinear, dimmed, lifted by ambient light,
noisy): decoded to within 0.05 projector px of the truth, or, for a single period read without
unwrapping, as coarse as the decode says. A description that would mislead is refused with numbers."""

from __future__ import annotations

import re
from typing import Any

import cv2
import numpy as np
import pytest
from pydantic import ValidationError

from rig.patterns.described import decode_described, described_patterns
from rig.patterns.spec import PatternSpec

WIDTH, HEIGHT = 400, 300
CAMERA = (360, 260)
MICRO = [16.0, 15.0, 15.1, 15.3, 18.4, 18.8, 19.5]  # the first N steps, the others a frame each


def _truth() -> tuple[np.ndarray, np.ndarray]:
    """The projector coordinate each camera pixel sees: a scale, a shear and a gentle bend."""
    rows, columns = np.mgrid[0 : CAMERA[1], 0 : CAMERA[0]].astype(np.float32)
    u = 12.3 + 1.02 * columns + 0.04 * rows + 2e-4 * (columns - 180) ** 2
    v = 9.7 + 1.05 * rows - 0.03 * columns
    return u, v


def _seen(patterns: list[np.ndarray], seed: int = 0) -> list[np.ndarray]:
    u, v = _truth()
    rng = np.random.default_rng(seed)
    frames = []
    for pattern in patterns:
        image = cv2.remap(pattern.astype(np.float32), u, v, cv2.INTER_LINEAR)
        frames.append(np.clip(20 + 0.7 * image + rng.normal(0, 1.5, image.shape), 0, 255).astype(np.uint8))
    return frames


def _phase(phase: dict[str, Any], **projector: Any) -> PatternSpec:
    return PatternSpec.model_validate(
        {"projector": {"resolution": [WIDTH, HEIGHT], **projector}, "phase": {"axes": ["columns", "rows"], **phase}}
    )


def _errors(spec: PatternSpec) -> tuple[np.ndarray, np.ndarray, Any]:
    """Decoded minus true coordinates where the camera sees the projector (a pixel beyond its edge,
    dimly lit by the blur across it, has no true coordinate), and the decode."""
    found = decode_described(_seen(described_patterns(spec)), spec, 255)
    u, v = _truth()
    assert found.u is not None and found.v is not None
    seen = found.valid & (u > -0.5) & (u < WIDTH - 0.5) & (v > -0.5) & (v < HEIGHT - 0.5)
    return found.u[seen] - u[seen], found.v[seen] - v[seen], found


FAMILIES: dict[str, dict[str, Any]] = {
    "a list per axis": {  # other periods for rows than for columns, as a calibration sequence may have
        "frequencies": {
            "columns": [{"period_px": 420, "steps": 6}, {"period_px": 64, "steps": 4}, {"period_px": 16, "steps": 8}],
            "rows": [{"period_px": 320, "steps": 6}, {"period_px": 14, "steps": 8}],
        },
        "unwrap": "hierarchical",
    },
    "micro phase shifting": {
        "frequencies": [{"period_px": p, "steps": 5 if i == 0 else 1} for i, p in enumerate(MICRO)],
        "unwrap": "micro",
    },
    "modulated phase shifting": {
        "frequencies": [{"period_px": 400, "steps": 6}, {"period_px": 16, "steps": 8}],
        "unwrap": "hierarchical",
        "modulation": {"period_px": 6, "steps": 3},
    },
}


@pytest.mark.parametrize("name", list(FAMILIES))
def test_each_phase_family_decodes_within_a_twentieth_of_a_projector_pixel(name: str) -> None:
    du, dv, found = _errors(_phase(FAMILIES[name]))
    assert found.valid.mean() > 0.95, found.counts
    for error in (du, dv):
        assert np.sqrt(np.mean(error**2)) < 0.05 and np.percentile(np.abs(error), 99.5) < 0.2


def test_a_single_period_read_without_unwrapping_is_as_coarse_as_it_says() -> None:
    single = {"columns": [{"period_px": 400, "steps": 8}], "rows": [{"period_px": 300, "steps": 8}]}
    spec = _phase({"frequencies": single, "unwrap": "none"})
    du, dv, found = _errors(spec)
    assert found.valid.mean() > 0.95
    for error, axis in ((du, "columns"), (dv, "rows")):
        stated = found.counts[f"phase_noise_millipx_{axis}"] / 1000
        measured = float(np.median(np.abs(error - np.median(error)))) * 1.4826  # a robust sigma
        assert measured > 0.05 and stated / 1.5 < measured < stated * 1.5, (axis, stated, measured)


def test_a_diamond_dmds_column_convention_is_a_setting() -> None:
    centred = PatternSpec.model_validate(
        {"projector": {"resolution": [200, 60], "pixel_geometry": "diamond"}, "gray": {"axes": ["columns"]}}
    )
    sampled = PatternSpec.model_validate(
        {
            "projector": {"resolution": [200, 60], "pixel_geometry": "diamond", "diamond_column": "sampled"},
            "gray": {"axes": ["columns"]},
        }
    )
    from rig.patterns.diamond import first_virtual_column

    shown = first_virtual_column(100, 60)  # the virtual column each mirror shows
    for spec, offset in ((centred, 0.5), (sampled, 0.0)):
        mirrors = [np.clip(20 + 0.7 * p.astype(np.float32), 0, 255).astype(np.uint8) for p in described_patterns(spec)]
        found = decode_described(mirrors, spec, 255)  # a camera that sees each mirror as a pixel
        assert found.u is not None and found.valid.all()
        assert np.array_equal(found.u, shown + offset)


@pytest.mark.parametrize(
    ("phase", "message"),
    [
        (
            {"frequencies": [{"period_px": 64, "steps": 8}], "unwrap": "none"},
            r"the longest period, 64 px, repeats 6.25 times over the 400 columns",
        ),
        (
            {
                "frequencies": [{"period_px": p, "steps": 5 if i == 0 else 1} for i, p in enumerate([16, 18, 20, 22])],
                "unwrap": "micro",
            },
            r"periods \[16\.0, 18\.0, 20\.0, 22\.0\] read columns \d+ and \d+ alike \(their single frames differ by "
            r"0\.0\d\d of the fringe amplitude",
        ),
        (
            {"frequencies": [{"period_px": 16, "steps": 5}, {"period_px": 18, "steps": 3}], "unwrap": "micro"},
            r"frequencies\[1\]\.steps 3: micro phase shifting shows every period after the first once",
        ),
        (
            {"frequencies": {"columns": [{"period_px": 400, "steps": 4}]}, "unwrap": "none"},
            r"frequencies: lists for \['columns'\], but the axes are \['columns', 'rows'\]",
        ),
        (
            {"frequencies": [{"period_px": 16, "steps": 1}], "unwrap": "gray"},
            r"frequencies\[0\]\.steps 1: an N-step phase needs 3 or more",
        ),
    ],
)
def test_a_description_that_would_mislead_is_refused_with_its_numbers(phase: dict[str, Any], message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        _phase(phase)


def test_a_description_that_runs_but_misleads_is_warned_with_numbers() -> None:
    from rig.patterns.described_checks import decoded_warnings

    shown = _phase({"frequencies": [{"period_px": p, "steps": 8} for p in (16, 17.5, 19)], "unwrap": "heterodyne"})
    frames = _seen(described_patterns(shown))
    assert decoded_warnings(shown, decode_described(frames, shown, 255)) == []
    said = _phase({"frequencies": [{"period_px": p, "steps": 8} for p in (16, 17.5, 20)], "unwrap": "heterodyne"})
    warnings = decoded_warnings(said, decode_described(frames, said, 255))
    assert re.search(r"only \d+% of the 93\d\d\d lit pixels decoded \(.*unwrap doubtful columns", warnings[0])
    assert all(re.search(r"decode beyond the projector's (400 columns|300 rows)", w) for w in warnings[1:])
    single = _phase({"frequencies": [{"period_px": 420, "steps": 8}], "unwrap": "none"})
    found = decode_described(_seen(described_patterns(single)), single, 255)
    stated = [w for w in decoded_warnings(single, found) if "read without unwrapping" in w]
    assert len(stated) == 2 and all(re.search(r"times 420 / 2 pi \(median 0\.\d\d px here\)", w) for w in stated)
    spanning = _phase({"frequencies": [{"period_px": 400, "steps": 8}, {"period_px": 16, "steps": 8}],
                       "unwrap": "hierarchical"})  # fmt: skip
    found = decode_described(_seen(described_patterns(spanning)), spanning, 255)
    ends = [w for w in decoded_warnings(spanning, found) if "ends within" in w]
    assert len(ends) == 1 and "the longest period, 400 px, ends within 4 px of the 400 columns' end" in ends[0]
