"""Pattern descriptions of other systems' captures: every convention decodes to the projector pixel
that showed it, and the real OpenCV GrayCodePattern captures decode where the board was lit."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest
from pydantic import ValidationError

from rig.calibrate.foreign import ForeignCalibrationOptions, read_foreign_calibration
from rig.errors import DecodeError
from rig.patterns.described import decode_described, described_patterns
from rig.patterns.gray import GrayCodec, GrayParams
from rig.patterns.phase import PhaseCodec, PhaseParams
from rig.patterns.spec import FrameFiles, GrayCode, PatternSpec, ProjectorSpace, opencv_graycode
from rig.pipeline.dense import PairTriangulator
from tests.conftest import shared_data

WIDTH, HEIGHT = 200, 120


def _seen(patterns: list[np.ndarray], seed: int = 0) -> list[np.ndarray]:
    """The patterns as a camera that sees the projector pixel for pixel would: dimmed, lifted by
    ambient light, noisy."""
    rng = np.random.default_rng(seed)
    return [np.clip(20 + 0.7 * p + rng.normal(0, 2.0, p.shape), 0, 255).astype(np.uint8) for p in patterns]


CONVENTIONS: list[dict[str, Any]] = [
    {},
    {"axes": ("rows", "columns"), "white_black": "last"},
    {"order": "lsb_first", "layout": "grouped"},
    {"code": "binary", "polarity": "lit_is_zero"},
    {"reference": "threshold", "white_black": "last"},
    {"white_black": "none", "axes": ("columns", "rows")},
    {"bits": 9},
]


@pytest.mark.parametrize(
    "convention", CONVENTIONS, ids=lambda c: ",".join(f"{k}={v}" for k, v in c.items()) or "default"
)
def test_every_convention_decodes_to_the_pixel_that_showed_it(convention: dict[str, Any]) -> None:
    spec = PatternSpec(projector=ProjectorSpace(resolution=(WIDTH, HEIGHT)), gray=GrayCode(**convention))
    patterns = described_patterns(spec)
    assert len(patterns) == len(spec.roles())
    found = decode_described(_seen(patterns), spec, 255)
    columns, rows = np.meshgrid(np.arange(WIDTH), np.arange(HEIGHT))
    assert found.valid.mean() > 0.99
    if "columns" in spec.gray.axes:
        assert found.u is not None and np.array_equal(found.u[found.valid], columns[found.valid])
    if "rows" in spec.gray.axes:
        assert found.v is not None and np.array_equal(found.v[found.valid], rows[found.valid])


def test_a_skipped_finest_bit_and_a_half_pixel_convention_place_the_pixel_in_its_span() -> None:
    spec = PatternSpec(
        projector=ProjectorSpace(resolution=(WIDTH, HEIGHT), first_pixel_centre=0.5),
        gray=GrayCode(skipped_low_bits=1),
    )
    found = decode_described(_seen(described_patterns(spec)), spec, 255)
    columns = np.broadcast_to(np.arange(WIDTH), (HEIGHT, WIDTH))
    assert found.u is not None
    assert np.array_equal(found.u[found.valid], (columns // 2 * 2 + 0.5 + 0.5)[found.valid])


def test_a_description_that_cannot_hold_is_refused_naming_the_field() -> None:
    with pytest.raises(ValidationError, match="reference threshold needs the white and black frames"):
        GrayCode(reference="threshold", white_black="none")
    with pytest.raises(ValidationError, match=r"gray\.bits 7: too few for 200 columns"):
        PatternSpec(projector=ProjectorSpace(resolution=(WIDTH, HEIGHT)), gray=GrayCode(bits=7))
    with pytest.raises(ValidationError, match="axes"):
        GrayCode(axes=("columns", "columns"))
    with pytest.raises(ValidationError, match="extra_forbidden"):
        FrameFiles(files="*.png", colour="grey")  # type: ignore[call-arg]
    spec = PatternSpec(projector=ProjectorSpace(resolution=(WIDTH, HEIGHT)), gray=GrayCode())
    frames = _seen(described_patterns(spec))
    counted = rf"has {len(frames)} frames \(columns: 16 Gray; white and black 2\), {len(frames) - 1} were given"
    with pytest.raises(DecodeError, match=counted):
        decode_described(frames[:-1], spec, 255)


def test_opencv_graycode_captures_of_a_real_board_decode_where_the_board_is_lit() -> None:
    """kamino410/procam-calibration capture_0: 42 frames of a real 1024x768 projector on a board,
    in OpenCV GrayCodePattern's order."""
    folder = shared_data("procam-calibration", "sample_data", "capture_0")
    files = sorted(folder.glob("graycode_*.png"))
    frames = [cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in files]
    spec = opencv_graycode(1024, 768, "graycode_*.png")
    assert len(spec.roles()) == len(frames) == 42
    found = decode_described(frames, spec, 255)
    assert found.u is not None and found.v is not None
    assert found.valid.mean() > 0.3  # the lit board and wall in view
    u, v = found.u[found.valid], found.v[found.valid]
    assert u.min() >= 0 and u.max() <= 1023 and v.min() >= 0 and v.max() <= 767
    # the code varies smoothly across the image: neighbours decode to neighbouring projector pixels
    step = np.abs(np.diff(found.u, axis=1))
    both = found.valid[:, 1:] & found.valid[:, :-1]
    assert np.median(step[both]) <= 1.0 and np.mean(step[both] > 8) < 0.02


def test_a_code_step_counts_the_calibrations_pixels_per_code() -> None:
    spec = PatternSpec(projector=ProjectorSpace(resolution=(WIDTH, HEIGHT), code_step_px=2), gray=GrayCode())
    assert spec.extent("columns") == WIDTH // 2 and len(spec.roles()) == 2 + 2 * 7  # 100 codes: 7 bits
    found = decode_described(_seen(described_patterns(spec)), spec, 255)
    columns = np.broadcast_to(np.arange(WIDTH), (HEIGHT, WIDTH))
    assert found.u is not None and found.valid.mean() > 0.99
    assert np.array_equal(found.u[found.valid], (columns // 2 * 2)[found.valid])


@pytest.mark.parametrize("pose", [0, 1])
def test_the_real_board_is_flat_and_where_the_camera_alone_puts_it(pose: int) -> None:
    """procam-calibration's result counts two projector pixels per code (its graycode_step 2: its
    principal point (737, 1358) is that of a 2048x1536 image) although its patterns are 1024x768
    with a code per pixel. Described so, each board reconstructs flat to the Gray code's step
    (about 9.6 units of depth per code at 3.5 m with its 645-unit baseline: 2.8 rms) and at the
    depth the camera alone gives it (solvePnP, 75-unit squares as in the authors' command)."""
    sample = shared_data("procam-calibration", "sample_data")
    frames = [
        cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in sorted((sample / f"capture_{pose}").glob("graycode_*.png"))
    ]
    spec = PatternSpec(
        projector=ProjectorSpace(resolution=(2048, 1536), code_step_px=2),
        gray=GrayCode(axes=("columns", "rows"), white_black="last"),
    )
    calibration = read_foreign_calibration(
        sample / "calibration_result.xml", ForeignCalibrationOptions(projector_resolution=(2048, 1536))
    )
    grid, valid = PairTriangulator(calibration.camera, calibration.projector).triangulate(
        decode_described(frames, spec, 255)
    )
    found, corners = cv2.findChessboardCorners(frames[40], (9, 7))
    assert found
    board = np.zeros(frames[40].shape, np.uint8)
    cv2.fillConvexPoly(board, cv2.convexHull(corners.reshape(-1, 2)).astype(np.int32), 1)
    points = grid[(board > 0) & valid]
    centre = points.mean(axis=0)
    normal = np.linalg.svd(points - centre, full_matrices=False)[2][2]
    assert np.sqrt(np.mean(((points - centre) @ normal) ** 2)) < 4.0  # 3.41 and 1.34 measured
    squares = np.zeros((63, 3))
    squares[:, :2] = np.mgrid[0:9, 0:7].T.reshape(-1, 2) * 75.0
    camera = calibration.camera
    _, rotation, translation = cv2.solvePnP(squares, corners, camera.K, camera.dist)
    alone = (squares @ cv2.Rodrigues(rotation)[0].T + translation.ravel()).mean(axis=0)
    assert abs(centre[2] - alone[2]) < 0.02 * alone[2]


@pytest.mark.parametrize("directions", ["columns", "both"])
def test_slrigs_own_gray_frames_read_as_their_description_says(directions: str) -> None:
    """The gray codec describes its frames; the described decoder gives its correspondence bit for bit."""
    codec = GrayCodec((WIDTH, HEIGHT), GrayParams(directions=directions))  # type: ignore[arg-type]
    spec = codec.description()
    frames = _seen(codec.patterns(), seed=3)
    assert len(spec.roles()) == codec.frame_count
    own, described = codec.decode(frames, 255), decode_described(frames, spec, 255)
    assert np.array_equal(own.valid, described.valid)
    for axis in ("u", "v"):
        mine, theirs = getattr(own, axis), getattr(described, axis)
        assert (mine is None) == (theirs is None)
        if mine is not None:
            assert np.array_equal(mine[own.valid], theirs[own.valid])


@pytest.mark.parametrize("directions", ["columns", "both"])
def test_slrigs_own_phase_frames_read_as_their_description_says(directions: str) -> None:
    """The phase codec describes its frames (half-period Gray unwrapping); the described decoder
    gives its correspondence to float precision."""
    codec = PhaseCodec((WIDTH, HEIGHT), PhaseParams(directions=directions, steps=6, period_px=20))  # type: ignore[arg-type]
    spec = codec.description()
    frames = _seen(codec.patterns(), seed=5)
    assert len(spec.roles()) == codec.frame_count
    own, described = codec.decode(frames, 255), decode_described(frames, spec, 255)
    agree = own.valid == described.valid
    assert agree.mean() > 0.999 and own.valid.sum() > 0.5 * own.valid.size
    both = own.valid & described.valid
    for axis in ("u", "v"):
        mine, theirs = getattr(own, axis), getattr(described, axis)
        assert (mine is None) == (theirs is None)
        if mine is not None:
            assert np.abs(mine[both] - theirs[both]).max() < 1e-3
