"""A diamond-pixel DMD (LightCrafter 4500: 912x1140 mirrors, 1824 virtual columns): captures whose
frames hold the mirrors' images, projected on the simulated bench through the DMD's geometry,
reconstruct as accurately as a square-pixel projector of the same code density."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest
import yaml

from rig.assembly import open_rig
from rig.config import config_from_dict
from rig.patterns.described import described_patterns
from rig.patterns.diamond import mirror_image, virtual_image
from rig.patterns.spec import PatternSpec
from tests.conftest import default_config_data
from tests.test_reconstruct import _opencv_calibration, reconstructed_error

VIRTUAL = [1824, 1140]
FAMILIES = {
    "gray": {"gray": {"axes": ["columns", "rows"], "white_black": "first"}},
    "phase": {
        "phase": {"frequencies": [{"period_px": p, "steps": 6} for p in (1824, 152, 24)], "unwrap": "hierarchical"}
    },
}


def test_mirror_and_virtual_images_are_each_others_inverse() -> None:
    mirrors = np.arange(4 * 3, dtype=np.uint8).reshape(4, 3) + 1
    virtual = virtual_image(mirrors)
    assert virtual.shape == (4, 6)
    assert virtual[0].tolist() == [1, 1, 2, 2, 3, 3]
    assert virtual[1].tolist() == [0, 4, 4, 5, 5, 6]  # odd rows half a mirror to the right
    assert np.array_equal(mirror_image(virtual), mirrors)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("diamond")
    data = default_config_data()
    projector = data["projectors"][0]
    projector["resolution"] = VIRTUAL  # the DMD's virtual grid, square pixels of half a mirror pitch
    projector["geometry"]["intrinsics"] = {"fx": 2670.0, "fy": 2670.0, "cx": 911.5, "cy": 569.5}
    config = config_from_dict(data, "diamond bench")
    with open_rig(config) as rig:
        for family, block in FAMILIES.items():
            for geometry, step in (("diamond", 1), ("square", 2)):
                spec = PatternSpec.model_validate(
                    {"projector": {"resolution": VIRTUAL, "pixel_geometry": geometry, "code_step_px": step}, **block}
                )
                frames = folder / f"{family}_{geometry}"
                frames.mkdir()
                for i, pattern in enumerate(described_patterns(spec)):
                    rig.projectors[0].show(virtual_image(pattern) if geometry == "diamond" else pattern)
                    cv2.imwrite(str(frames / f"{i:02d}.png"), rig.cameras[0].capture().image)
                (folder / f"{family}_{geometry}.yaml").write_text(yaml.safe_dump(spec.model_dump(mode="json")))
        assert rig.truth is not None
        truth = rig.truth.ground_truth(0, 0)
        camera, projector_model = rig.camera_models[0], rig.projector_models[0]
    calibration = _opencv_calibration(folder / "calibration.xml", camera, projector_model)
    return {"folder": folder, "config": config, "truth": truth, "camera": camera, "calibration": calibration}


@pytest.mark.parametrize("family", list(FAMILIES))
def test_a_diamond_dmd_reconstructs_as_well_as_square_pixels_of_the_same_density(
    rendered: dict[str, Any], family: str
) -> None:
    diamond, covered = reconstructed_error(rendered, f"{family}_diamond")
    square, square_covered = reconstructed_error(rendered, f"{family}_square")
    print(f"diamond {family}: {diamond:.4f} mm rms ({covered} px), square {square:.4f} mm ({square_covered} px)")
    assert diamond <= 1.1 * square, (family, diamond, square)
    assert covered >= 0.95 * square_covered, (family, covered, square_covered)
