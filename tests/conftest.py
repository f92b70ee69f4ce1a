"""Shared fixtures: configs of the simulated bench (full size and a small fast one)."""

from __future__ import annotations

import copy
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from rig.config import DEFAULT_CONFIG, RigConfig, load_config
from rig.geometry import CameraModel, look_at_rotation

REPO = Path(__file__).resolve().parent.parent


ONE_THREAD = ("SLRIG_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def pytest_configure(config: pytest.Config) -> None:
    """With one test process per core (xdist), each runs its pixel work on one thread: threads of
    two processes contending for two cores only wait on each other. Set before the workers start,
    which inherit the environment. Where the environment says not to write Python's bytecode
    (PYTHONDONTWRITEBYTECODE), the test run writes it all the same, beside the sources (in the
    `__pycache__` folders git ignores): the workers and the hundred-odd CLI and daemon processes the
    tests start would each compile rig's source again (0.9 s of CPU a process). Not under a prefix
    of its own (PYTHONPYCACHEPREFIX): Python then reads no installed package's bytecode either, and
    a clean clone's run compiled numpy, numba, SciPy and FastAPI again (74 MB; importing what a scan
    needs took 6.4 s of CPU in place of 1.7, and py-spy saw 21 s of the suite's CPU compiling)."""
    if os.environ.get("PYTHONDONTWRITEBYTECODE") and not os.environ.get("PYTEST_XDIST_WORKER"):
        os.environ.pop("PYTHONDONTWRITEBYTECODE")
        sys.dont_write_bytecode = False
    if config.getoption("numprocesses", None) not in (None, 0) and not os.environ.get("PYTEST_XDIST_WORKER"):
        for name in ONE_THREAD:
            os.environ.setdefault(name, "1")
    if os.environ.get("SLRIG_THREADS") == "1":
        import cv2

        cv2.setNumThreads(1)


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """`-n auto` (pyproject's addopts): a worker per core and one more. Each test process runs its
    pixel work on one thread (pytest_configure), and many tests spend part of their time waiting on
    the CLI and daemon processes they start, on sockets and on a browser: with a worker per core, two
    cores were 174 % busy over the suite and a clean clone's run took 507 s; with one more, 189 % and
    429 s (idle, 2 cores, the same commit). xdist's own answer (None) where its environment variable
    PYTEST_XDIST_AUTO_NUM_WORKERS sets the count, or for `-n logical`."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS") or config.getoption("numprocesses", None) == "logical":
        return None
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return cores + 1


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--rig",
        default=None,
        metavar="BENCH_YAML",
        help="also run the device contracts (tests/test_contracts.py) on this real bench's devices",
    )


def make_device(
    width: int,
    height: int,
    f: float,
    position: tuple[float, float, float],
    target: tuple[float, float, float] = (0.0, 0.0, 0.0),
    dist: tuple[float, ...] = (),
    projection: str = "pinhole",
) -> CameraModel:
    """A camera or projector at `position` looking at `target`, principal point at the centre."""
    pos = np.array(position, float)
    R = look_at_rotation(pos, np.array(target, float), np.array([0.0, 1.0, 0.0]))
    K = np.array([[f, 0.0, width / 2 - 0.5], [0.0, f, height / 2 - 0.5], [0.0, 0.0, 1.0]])
    return CameraModel(width, height, K, R, -R @ pos, dist=np.array(dist), projection=projection)  # type: ignore[arg-type]


def face_normals(points: np.ndarray, tri: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(F, 3) unit normals of triangles `tri`, toward the camera (against corner 0's ray): what the
    ring surface's compiled triangle tests give (rig.kernels.triangles), as numpy."""
    p = points[tri]
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    face /= np.maximum(np.linalg.norm(face, axis=1), 1e-300)[:, None]
    face[np.einsum("ij,ij->i", face, directions[tri[:, 0]]) > 0] *= -1
    return face


def face_weights(edge_mm: np.ndarray) -> np.ndarray:
    """(F,) 1 / each triangle's longest edge, from its edges' lengths (F, 3) (the weight of a face's
    normal in its corners', rig.pipeline.normals.vertex_normals)."""
    return 1.0 / np.maximum(edge_mm.max(axis=1), 1e-9)


def default_config_data() -> dict[str, Any]:
    return yaml.safe_load(DEFAULT_CONFIG.read_text())


def small_config_data() -> dict[str, Any]:
    """The default bench at a quarter of the resolution (same field of view): fast scans."""
    data = copy.deepcopy(default_config_data())
    cam = data["cameras"][0]
    cam["resolution"] = [320, 256]
    cam["geometry"]["intrinsics"] = {"fx": 450.0, "fy": 450.0, "cx": 159.5, "cy": 127.5}
    proj = data["projectors"][0]
    proj["resolution"] = [256, 192]
    proj["geometry"]["intrinsics"] = {"fx": 375.0, "fy": 375.0, "cx": 127.5, "cy": 95.5}
    data["scan"]["phase"] = {"steps": 6, "period_px": 8}
    return data


def shared_data(*parts: str) -> Path:
    """A file or folder of the real captures made by other people (`$SLRIG_TEST_DATA`, else
    ../shared/data beside the project); the test is skipped, saying why, where it is absent."""
    root = Path(os.environ["SLRIG_TEST_DATA"]) if os.environ.get("SLRIG_TEST_DATA") else REPO.parent / "shared" / "data"
    path = root.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"real data {'/'.join(parts)} is not here ({root}; set SLRIG_TEST_DATA to the shared data folder)")
    return path


def write_config(tmp_path: Path, data: dict[str, Any], name: str = "rig.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture
def small_config(tmp_path: Path) -> RigConfig:
    return load_config(write_config(tmp_path, small_config_data()))


@pytest.fixture
def small_config_path(tmp_path: Path) -> Path:
    return write_config(tmp_path, small_config_data())


def ply_vertex(data: bytes) -> Any:
    """A PLY file's vertex records (a structured array)."""
    import io

    from plyfile import PlyData

    return PlyData.read(io.BytesIO(data))["vertex"].data


def ply_xyz(data: bytes) -> Any:
    """The x, y, z columns of a PLY file's vertices (N, 3)."""
    import numpy as np

    vertex = ply_vertex(data)
    return np.stack([vertex["x"], vertex["y"], vertex["z"]], axis=1)


def wait_done(client: Any, job_id: str, collection: str = "scans", timeout_s: float = 120.0) -> dict[str, Any]:
    """Poll a job through any HTTP client with .get (TestClient, httpx.Client with a base_url)
    until it leaves queued and running."""
    import time

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job: dict[str, Any] = client.get(f"/v1/{collection}/{job_id}").json()
        if job["state"] not in ("queued", "running"):
            return job
        time.sleep(0.05)
    raise AssertionError(f"{job_id} did not finish")


UNCLIPPED_FULL_SCALE = 65535


def unclipped(patterns: list[np.ndarray]) -> list[np.ndarray]:
    """8-bit patterns as a camera with headroom reads them: on 16-bit counts (x 256, full scale
    UNCLIPPED_FULL_SCALE), so white is not at full scale, which a decoder must take for clipped
    (rig.patterns.saturation); the values are the patterns' own, exactly."""
    return [p.astype(np.uint16) * np.uint16(256) for p in patterns]
