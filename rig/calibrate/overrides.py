"""A calibration's board and lens model given with the request (`slrig calibrate --board/--model`,
POST /v1/calibrations' `board`/`model`) instead of the config's, validated as the config file is."""

from __future__ import annotations

from rig.config import RigConfig, config_from_dict
from rig.errors import ConfigError

BOARD_FORMAT = "KIND:COLSxROWS:SQUARE_MM[:MARKER_MM[:DICTIONARY]]"


def board_fields(text: str, field: str = "--board") -> dict[str, object]:
    """KIND:COLSxROWS:SQUARE_MM[:MARKER_MM[:DICTIONARY]] (squares, not inner corners) as BoardConfig
    fields; ConfigError naming `field` for text that is not in that form."""
    parts = text.split(":")
    try:
        if not 3 <= len(parts) <= 5:
            raise ValueError
        cols, rows = (int(n) for n in parts[1].lower().split("x"))
        fields: dict[str, object] = {"kind": parts[0], "squares": [cols, rows], "square_mm": float(parts[2])}
        if len(parts) > 3:
            fields["marker_mm"] = float(parts[3])
    except ValueError:
        problem = f"{field}: {text!r} is not {BOARD_FORMAT} (checker:10x8:75)"
        raise ConfigError(field, [problem]) from None
    return fields | ({"dictionary": parts[4]} if len(parts) == 5 else {})


def calibration_overrides(
    config: RigConfig,
    board: str | None,
    model: str | None,
    names: tuple[str, str] = ("--board", "--model"),
    device_models: tuple[str | None, str | None] = (None, None),
    world: str | None = None,
) -> RigConfig:
    """The config with another board and lens model (and the cameras' and projectors' own,
    `device_models`); ConfigError names them as `names` does."""
    if board is None and model is None and device_models == (None, None) and world is None:
        return config
    board_name, model_name = names
    data = config.model_dump(mode="json")
    if model is not None:
        data["calibration"]["model"] = model
    for key, chosen in zip(("camera_model", "projector_model"), device_models, strict=True):
        if chosen is not None:
            data["calibration"][key] = chosen
    if board is not None:
        data["calibration"]["board"] |= board_fields(board, board_name)
    if world is not None:
        data["calibration"]["world"] = world
    try:
        return config_from_dict(data, f"{board_name}/{model_name}")
    except ConfigError as exc:
        renamed = (
            ("calibration.board.", f"{board_name} "),
            ("calibration.board", board_name),
            ("calibration:", f"{model_name}:"),
        )
        problems = [p.replace(*renamed[0]).replace(*renamed[1]).replace(*renamed[2]) for p in exc.problems]
        if board_name.startswith("--"):  # the command line's own names for the devices' models
            problems = [
                p.replace("camera_model '", "--camera-model '").replace("projector_model '", "--projector-model '")
                for p in problems
            ]
        raise ConfigError(f"{board_name}/{model_name}", problems) from None
