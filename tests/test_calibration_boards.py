"""Calibration boards in a config: a board of one parity is accepted with a warning about its
orientation; one that cannot be printed or detected is refused naming the field."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from rig.calibrate.boards import Board
from rig.config import BoardConfig


def test_a_checkerboard_of_two_even_counts_is_accepted_with_a_warning() -> None:
    config = BoardConfig(squares=(10, 8), square_mm=25.0)  # procam-calibration's 9x7 inner corners
    warning = config.orientation_warning()
    assert warning is not None and "two even" in warning and "quarter turn" in warning
    board = Board(config)
    assert board.corner_count == 9 * 7
    assert np.allclose(board.object_points(np.array([0]))[0, :2], [-4 * 25.0, 3 * 25.0])
    assert BoardConfig(squares=(9, 7)).orientation_warning() is not None  # two odd
    assert BoardConfig(squares=(10, 7)).orientation_warning() is None
    assert BoardConfig(kind="charuco", squares=(10, 8), square_mm=20.0, marker_mm=15.0).orientation_warning() is None


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"squares": (2, 5)}, "squares [2, 5]: a board needs 3 to 100 squares"),
        ({"kind": "charuco", "square_mm": 10.0, "marker_mm": 12.0}, "marker_mm 12 must be smaller than square_mm 10"),
    ],
)
def test_a_board_that_cannot_be_used_is_refused_naming_the_field(fields: dict[str, object], message: str) -> None:
    with pytest.raises(ValidationError, match=message.replace("[", r"\[").replace("]", r"\]")):
        BoardConfig(**fields)  # type: ignore[arg-type]
