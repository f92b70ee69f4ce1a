"""Phase-shift captures in other systems' conventions (Gray-code, heterodyne and single-period-cue
unwrapping; other shift directions and start phases), rendered on the simulated bench, saved as
files and reconstructed by `reconstruct_folder`: as accurate as slrig's own phase codec."""

from __future__ import annotations

from typing import Any

import cv2
import pytest
import yaml
from pydantic import ValidationError

from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.patterns.described import described_patterns
from rig.patterns.spec import PatternSpec
from rig.pipeline.scan import run_scan
from tests.test_reconstruct import _opencv_calibration, _rms_against_truth, reconstructed_error

PROJECTOR = {"resolution": [1024, 768]}
DESCRIPTIONS: dict[str, dict[str, Any]] = {
    "gray": {
        "phase": {"frequencies": [{"period_px": 16, "steps": 8}], "unwrap": "gray", "shift": "minus"},
        "gray": {"white_black": "first"},
    },
    "heterodyne2": {
        "phase": {
            "frequencies": [{"period_px": 64, "steps": 8}, {"period_px": 68, "steps": 8}],
            "unwrap": "heterodyne",
            "start_deg": 90,
        },
    },
    "heterodyne3": {
        "phase": {
            "frequencies": [{"period_px": p, "steps": 8} for p in (16, 17.5, 19)],
            "unwrap": "heterodyne",
            "white_black": "last",
        },
    },
    "cue": {
        "phase": {
            "frequencies": [{"period_px": p, "steps": 8} for p in (1024, 128, 16)],
            "unwrap": "hierarchical",
            "shift": "minus",
            "start_deg": -45,
        },
    },
}


@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("phase")
    config = load_config()
    with open_rig(config) as rig:
        for name, description in DESCRIPTIONS.items():
            spec = PatternSpec.model_validate({"projector": PROJECTOR, **description})
            frames = folder / name
            frames.mkdir()
            for i, pattern in enumerate(described_patterns(spec)):
                rig.projectors[0].show(pattern)
                cv2.imwrite(str(frames / f"frame_{i:02d}.png"), rig.cameras[0].capture().image)
            (folder / f"{name}.yaml").write_text(yaml.safe_dump(spec.model_dump(mode="json")))
        own = run_scan(rig, "phase")
        assert rig.truth is not None
        truth = rig.truth.ground_truth(0, 0)
        camera, projector = rig.camera_models[0], rig.projector_models[0]
    data = config.model_dump(mode="json")
    data["scan"]["phase"] = {"steps": 8, "period_px": 64}
    with open_rig(config_from_dict(data, "period 64")) as rig:
        own_64 = run_scan(rig, "phase")
    calibration = _opencv_calibration(folder / "calibration.xml", camera, projector)
    own = {
        period: _rms_against_truth(scan.pairs[0].grid, camera, truth, False)
        for period, scan in ((16, own), (64, own_64))
    }
    return {
        "folder": folder,
        "config": config,
        "truth": truth,
        "camera": camera,
        "calibration": calibration,
        "own": own,
    }


@pytest.mark.parametrize("name", list(DESCRIPTIONS))
def test_each_phase_family_reconstructs_as_accurately_as_slrigs_own_phase(rendered: dict[str, Any], name: str) -> None:
    rms, covered = reconstructed_error(rendered, name)
    # against slrig's own phase codec of the same finest period (16 px, 64 for the two-frequency
    # heterodyne, whose beat must span 1024 px) and 8 steps
    own_rms, own_covered = rendered["own"][64 if name == "heterodyne2" else 16]
    assert rms <= 1.1 * own_rms, (name, rms, own_rms)
    assert covered >= 0.95 * own_covered, (name, covered, own_covered)


@pytest.mark.parametrize(
    ("phase", "message"),
    [
        ({"frequencies": [{"period_px": 16, "steps": 4}], "unwrap": "heterodyne"}, "two or more frequencies"),
        (
            {"frequencies": [{"period_px": 16, "steps": 4}, {"period_px": 18, "steps": 4}], "unwrap": "heterodyne"},
            "their beat spans 144 px, less than the 1024 columns",
        ),
        (
            {"frequencies": [{"period_px": 16, "steps": 4}, {"period_px": 128, "steps": 4}], "unwrap": "hierarchical"},
            "the longest period, 128 px, repeats 8 times over the 1024 columns",
        ),
        ({"frequencies": [{"period_px": 16, "steps": 4}], "unwrap": "gray"}, "the gray block"),
        ({"frequencies": [{"period_px": 16, "steps": 4}] * 2, "unwrap": "heterodyne"}, "repeat"),
        (
            {"frequencies": [{"period_px": p, "steps": 4} for p in (20, 24, 30)], "unwrap": "heterodyne"},
            "their beat spans 0 px",  # both beats 120 px: their own beat resolves nothing
        ),
        ({"frequencies": [{"period_px": 16, "steps": 2}], "unwrap": "gray"}, "steps"),
    ],
)
def test_a_phase_description_that_cannot_unwrap_is_refused(phase: dict[str, Any], message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        PatternSpec.model_validate({"projector": PROJECTOR, "phase": phase})


def test_roles_put_each_axis_phase_frames_before_its_gray_code() -> None:
    spec = PatternSpec.model_validate(
        {
            "projector": PROJECTOR,
            "phase": {**DESCRIPTIONS["gray"]["phase"], "axes": ["columns", "rows"]},
            "gray": {"axes": ["columns", "rows"], "white_black": "none"},
        }
    )
    roles = spec.roles()
    kinds = [r.shows for r in roles]
    # columns: 8 steps, 6 bits of 64 periods with inverses; rows: 8 steps, 6 bits of 48 periods
    assert kinds == ["phase"] * 8 + ["bit"] * 12 + ["phase"] * 8 + ["bit"] * 12
    assert spec.extent("columns") == 64 and spec.extent("rows") == 48
