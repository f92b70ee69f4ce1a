"""The CLI: scan outputs, error messages and exit codes, device faults."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import plyfile
import pytest

from rig.assembly import open_rig
from rig.cli import main
from rig.config import RigConfig, config_from_dict
from rig.errors import ScanError
from rig.pipeline.scan import run_scan
from tests.conftest import REPO, default_config_data, write_config


def test_scan_writes_a_complete_scan_directory(
    tmp_path: Path, small_config_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "scan1"
    assert main(["scan", "--config", str(small_config_path), "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["path"] == str(out)
    stored = ["cloud.ply", "depth_camera0.png", "manifest.json", "preview.png", "truth_error_mm.npy"]
    assert sorted(p.name for p in out.iterdir()) == stored
    assert not out.with_name("scan1.partial").exists()

    vertex = plyfile.PlyData.read(out / "cloud.ply")["vertex"]
    names = {p.name for p in vertex.properties}
    assert {"x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", "quality", "source"} <= names
    assert vertex.count == summary["points"] > 50_000
    normals = np.column_stack([vertex["nx"], vertex["ny"], vertex["nz"]])
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-4)
    assert np.ptp(vertex["red"]) > 50  # the lit frame's texture, not a constant
    errors = np.load(out / "truth_error_mm.npy")
    assert errors.dtype == np.float32 and errors.shape == (vertex.count,) and np.median(errors) < 0.2

    depth = cv2.imread(str(out / "depth_camera0.png"), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and depth.shape == (256, 320)
    seen = depth[depth > 0]
    assert seen.min() > 450 and seen.max() < 700  # the plane is about 600 mm away, the sphere nearer

    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "done"
    assert manifest["codec"]["name"] == "phase"
    assert manifest["economy"]["frames_projected"] == 2 + 6 + 2 * 6  # 64 half periods: 6 Gray bits
    assert manifest["economy"]["points"] == summary["points"]
    assert manifest["metrics"]["projector0/camera0"]["rms_mm"] < 0.5
    assert manifest["config"]["cameras"][0]["resolution"] == [320, 256]
    preview = cv2.imread(str(out / "preview.png"))
    assert preview is not None and preview.std() > 10


def test_scan_refuses_an_existing_output(
    tmp_path: Path, small_config_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "kept"
    out.mkdir()
    (out / "precious.txt").write_text("keep me")
    assert main(["scan", "--config", str(small_config_path), "--out", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["precious.txt"]


def test_save_frames_keeps_the_raw_captures(tmp_path: Path) -> None:
    from tests.conftest import small_config_data

    data = small_config_data()
    data["scan"]["save_frames"] = True
    data["scan"]["codec"] = "gray"
    out = tmp_path / "with-frames"
    assert main(["scan", "--config", str(write_config(tmp_path, data)), "--out", str(out)]) == 0
    folder = out / "frames" / "projector0_camera0"
    frames = sorted(folder.glob("*.png"))
    assert len(frames) == 2 + 2 * 8  # white, black, 8 Gray bits with inverses for 256 columns
    assert cv2.imread(str(frames[0]), cv2.IMREAD_UNCHANGED).shape == (256, 320)
    assert {p.name for p in folder.iterdir()} - {p.name for p in frames} == {"patterns.yaml"}  # what they show


def test_a_scan_with_save_frames_reprocesses_with_reconstruct_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.conftest import small_config_data

    data = small_config_data()
    data["scan"]["codec"] = "gray"
    data["output"] = {"data_dir": str(tmp_path / "data")}
    config = write_config(tmp_path, data)
    assert main(["scan", "--config", str(config), "--save-frames", "--json"]) == 0
    scanned = json.loads(capsys.readouterr().out)
    source = Path(scanned["path"])
    assert source.parent == tmp_path / "data" / "scans"  # <data_dir>/scans/<id>
    assert main(["reconstruct", str(source), "--json"]) == 0  # no --patterns, --calibration or --config
    again = json.loads(capsys.readouterr().out)
    assert Path(again["path"]).parent == source.parent and again["points"] == scanned["points"]
    first, second = (plyfile.PlyData.read(Path(p) / "cloud.ply")["vertex"] for p in (source, again["path"]))
    assert np.array_equal(first["x"], second["x"]) and np.array_equal(first["z"], second["z"])
    manifest = json.loads((Path(again["path"]) / "manifest.json").read_text())
    assert manifest["origin"]["reprocessed_from"] == source.name
    assert main(["reconstruct", str(source), "--patterns", "x.yaml"]) == 2
    assert "--patterns: a scan directory's manifest says what its frames are" in capsys.readouterr().err
    assert main(["reconstruct", str(source / "frames" / "projector0_camera0")]) == 2  # a frames folder alone
    assert "--calibration: " in capsys.readouterr().err


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d["cameras"][0].update(resolution=[1280]), "cameras[0].resolution"),
        (lambda d: d["simulation"].update(scene={"kind": "mesh", "path": "missing.stl"}), "mesh file not found"),
        (lambda d: d["scan"].update(codec="nope"), "scan.codec"),
    ],
)
def test_bad_input_exits_2_with_one_clear_message(tmp_path: Path, mutate, message: str) -> None:  # type: ignore[no-untyped-def]
    data = default_config_data()
    mutate(data)
    path = write_config(tmp_path, data)
    result = subprocess.run(
        [sys.executable, "-m", "rig.cli", "scan", "--config", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert result.stdout == ""


def test_unknown_codec_option_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["eval", "--codec", "moire"]) == 2
    err = capsys.readouterr().err
    assert "moire" in err and "gray, phase" in err


def test_unknown_scene_option_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["eval", "--scene", "teapot"]) == 2
    assert "neither a scene name" in capsys.readouterr().err


def test_camera_fault_fails_the_scan_and_leaves_the_projector_dark(small_config: RigConfig) -> None:
    data = small_config.model_dump()
    data["cameras"][0]["sim"]["faults"]["disconnect_after_frames"] = 5
    the_rig = open_rig(config_from_dict(data, "test"))
    try:
        with pytest.raises(ScanError, match="disconnected"):
            run_scan(the_rig)
        assert all(p.is_dark for p in the_rig.projectors)  # type: ignore[attr-defined]
    finally:
        the_rig.close()


def test_colour_camera_gives_a_coloured_cloud(tmp_path: Path) -> None:
    from tests.conftest import small_config_data

    data = small_config_data()
    data["cameras"][0]["color"] = True
    data["simulation"]["scene"] = {"kind": "sphere_on_plane", "sphere_albedo": [0.9, 0.3, 0.1], "plane_albedo": 0.6}
    out = tmp_path / "colour"
    assert main(["scan", "--config", str(write_config(tmp_path, data)), "--out", str(out)]) == 0
    vertex = plyfile.PlyData.read(out / "cloud.ply")["vertex"]
    rgb = np.column_stack([vertex["red"], vertex["green"], vertex["blue"]]).astype(float)
    on_sphere = vertex["z"] > 20.0
    assert on_sphere.sum() > 1000
    red, green, blue = rgb[on_sphere].mean(axis=0)
    assert red > 2 * green > 2 * blue  # the sphere's albedo, seen through the lit frame
    plane = rgb[~on_sphere]
    assert np.abs(plane[:, 0] - plane[:, 2]).mean() < 6  # the grey plane stays grey
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["metrics"]["projector0/camera0"]["rms_mm"] < 0.5


def test_progress_events_advance_through_the_stages(small_config: RigConfig) -> None:
    from rig.progress import ProgressEvent

    events: list[ProgressEvent] = []
    with open_rig(small_config) as the_rig:
        run_scan(the_rig, progress=events.append)
    fractions = [e.fraction for e in events]
    assert fractions == sorted(fractions) and fractions[-1] >= 0.9
    stages = [e.stage for e in events]
    assert stages.index("capture") < stages.index("decode") < stages.index("triangulate")
    assert all(e.elapsed_s >= 0 for e in events)
    assert events[-1].remaining_s is not None and events[-1].remaining_s < events[-1].elapsed_s


def _on_a_terminal(command: list[str], cwd: Path, timeout_s: float = 120.0) -> tuple[int, str]:
    """Run `command` with a pseudo-terminal as its stdin, stdout and stderr, as a person's shell
    does; its exit code and everything it drew."""
    import pty
    import select

    main_fd, child_fd = pty.openpty()
    env = {**os.environ, "PYTHONPATH": str(REPO), "COLUMNS": "100"}
    process = subprocess.Popen(command, stdin=child_fd, stdout=child_fd, stderr=child_fd, cwd=cwd, env=env)
    os.close(child_fd)
    drawn, deadline = b"", time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([main_fd], [], [], 0.2)
            if ready:
                try:
                    chunk = os.read(main_fd, 65536)
                except OSError:  # the terminal closed: the command ended
                    break
                if not chunk:
                    break
                drawn += chunk
            elif process.poll() is not None:
                break
        return process.wait(max(1.0, deadline - time.monotonic())), drawn.decode(errors="replace")
    finally:
        os.close(main_fd)
        if process.poll() is None:
            process.kill()


def test_a_long_command_draws_a_bar_on_a_terminal_lines_in_a_pipe_and_only_json_with_json(
    tmp_path: Path, small_config_path: Path
) -> None:
    calibrate = [sys.executable, "-m", "rig.cli", "calibrate", "camera", "--config", str(small_config_path)]
    code, drawn = _on_a_terminal([*calibrate, "--views", "3", "--out", str(tmp_path / "tty")], tmp_path)
    assert code == 0, drawn
    assert "\r[" in drawn and "view 3 of 3" in drawn and "100 % done" in drawn  # redrawn in place
    assert re.search(r"\(\d+\.\d s|\(\d+ s", drawn)  # times as a person reads them: 3.8 s
    piped = subprocess.run(
        [*calibrate, "--views", "3", "--out", str(tmp_path / "pipe")],
        capture_output=True, text=True, timeout=120, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(REPO)},
    )  # fmt: skip
    assert piped.returncode == 0 and "\r" not in piped.stderr
    assert piped.stderr.splitlines()[0].startswith("views: view 1 of 3 (")  # a line per stage
    assert "solve: 3 views" in piped.stderr and "calibration " in piped.stdout
    quiet = subprocess.run(
        [*calibrate, "--views", "3", "--out", str(tmp_path / "json"), "--json"],
        capture_output=True, text=True, timeout=120, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(REPO)},
    )  # fmt: skip
    assert quiet.returncode == 0 and quiet.stderr == ""
    assert json.loads(quiet.stdout)["views"] == 3  # one JSON object and nothing else


def test_inputs_that_crashed_are_refused_with_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A YAML nested hundreds deep (RecursionError), an API key file that is not UTF-8 (a
    traceback), an existing --out (not a config problem: a usage error)."""
    deep = tmp_path / "deep.yaml"
    deep.write_text("a: " + "[" * 600 + "]" * 600 + "\n")
    assert main(["scan", "--config", str(deep)]) == 2
    assert "(file): nested too deeply" in capsys.readouterr().err
    key = tmp_path / "key"
    key.write_bytes(b"\xff\xfe" + b"k" * 40)
    assert main(["serve", "--api-key-file", str(key), "--port", "1"]) == 2
    assert "--api-key-file: " in capsys.readouterr().err
    (tmp_path / "taken").mkdir()
    assert main(["scan", "--out", str(tmp_path / "taken")]) == 2
    err = capsys.readouterr().err
    assert "--out: " in err and "already exists" in err and "invalid config" not in err


def test_a_key_file_others_can_read_is_warned_about(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    import logging

    from rig.daemon.keys import load_api_key

    key = tmp_path / "key"
    key.write_text("k" * 40)
    key.chmod(0o600)
    with caplog.at_level(logging.WARNING, logger="rig.daemon.keys"):
        assert load_api_key(key, tmp_path) == "k" * 40
    assert not caplog.records
    key.chmod(0o644)
    with caplog.at_level(logging.WARNING, logger="rig.daemon.keys"):
        assert load_api_key(key, tmp_path) == "k" * 40
    assert "can be read by users other than its owner; chmod 600 it" in caplog.text


def test_help_and_commands_that_do_not_decode_import_neither_numba_nor_the_web_stack() -> None:
    script = (
        "import sys\n"
        "from rig.cli import main\n"
        "try:\n"
        "    main(['--help'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "print(sorted(m for m in ('numba', 'fastapi', 'uvicorn', 'starlette') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60, cwd=REPO)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_the_kernels_load_once_when_many_threads_first_need_them() -> None:
    script = (
        "import threading\n"
        "from rig.patterns import stream\n"
        "barrier, found = threading.Barrier(8), []\n"
        "def first_use():\n"
        "    barrier.wait()\n"
        "    found.append(callable(stream.kernels.contrast_and_lit))\n"
        "threads = [threading.Thread(target=first_use) for _ in range(8)]\n"
        "[t.start() for t in threads]\n"
        "[t.join(60) for t in threads]\n"
        "print(found.count(True))\n"
    )
    for _ in range(3):  # a half-loaded module seen by another thread shows up within a few runs
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, cwd=REPO)
        assert out.returncode == 0 and out.stdout.strip() == "8", out.stderr[-2000:]
