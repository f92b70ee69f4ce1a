"""The scanned face set of bench/recognition.py: every synthetic face (drivers/sim/faces.py) set on
the simulated bench and scanned with N evenly spaced rings; a scan's surface is its cloud and the
surface interpolated between its rings, as `slrig identify` reads a stored scan. Scans are kept in
a cache directory (one .npz each) so that a re-run only describes."""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drivers.sim import faces
from rig.assembly import open_rig
from rig.config import config_from_dict, load_config
from rig.pipeline.scan import run_scan
from rig.plan.ring_plan import pilot_views, plan_rings

# rigid poses of the neutral face: a turn about the view axis with a shift, and a small tilt
POSES: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "turned": ((0.0, 0.0, 30.0), (20.0, -15.0, 0.0)),
    "tilted": ((5.0, -5.0, 10.0), (-10.0, 10.0, 0.0)),
}


@dataclass(frozen=True)
class Case:
    """One face to scan: an identity with an expression, or its neutral face posed."""

    identity: int
    expression: str
    pose: str | None = None

    @property
    def name(self) -> str:
        return f"id{self.identity:02d}-{self.pose or self.expression}"

    @property
    def group(self) -> str:
        """gallery (the neutral scan), expression, or pose"""
        if self.pose is not None:
            return "pose"
        return "gallery" if self.expression == "neutral" else "expression"

    def face(self) -> faces.Face:
        face = faces.expression(faces.identity(self.identity), self.expression)
        if self.pose is not None:
            face = faces.posed(face, POSES[self.pose][0], (0.0, 0.0, 0.0))
        return face

    def position_mm(self) -> tuple[float, float, float]:
        return POSES[self.pose][1] if self.pose is not None else (0.0, 0.0, 0.0)


@dataclass(frozen=True, eq=False)
class FaceScan:
    case: Case
    rings: int
    points: np.ndarray  # (N, 3) mm: the cloud and the interpolated surface's vertices
    toward_viewer: np.ndarray  # (3,) the projector's axis, from the surface toward it
    seconds: float


def cases(identities: int) -> list[Case]:
    """Per identity: its five expressions (neutral first), then its neutral face in each pose."""
    found = []
    for i in range(identities):
        found += [Case(i, kind) for kind in faces.EXPRESSIONS]
        found += [Case(i, "neutral", pose) for pose in POSES]
    return found


def face_config(case: Case, folder: Path, rings: int | None, bench: Path | None = None) -> Any:
    """The bench (`bench`, a rig config; default: the default bench) with the face on its plane
    (and `rings` evenly spaced rings when given)."""
    path = case.face().write_ply(folder / f"{case.name}.ply")
    data = load_config(bench).model_dump(mode="json")
    data["simulation"]["scene"] = {"kind": "mesh", "path": str(path), "position_mm": list(case.position_mm())}
    if rings is not None:
        data["scan"]["codec"] = "rings"
        data["scan"]["rings"].update(rings=rings, radii_px=None)
    return config_from_dict(data, case.name)


def scan(case: Case, rings: int, cache: Path, bench: Path | None = None) -> FaceScan:
    """The face of `case` scanned with `rings` rings on `bench` (from the cache where it is there)."""
    stored = cache / f"{bench.stem if bench else 'sim'}-{case.name}-{rings}rings.npz"
    if stored.exists():
        with np.load(stored) as kept:
            return FaceScan(case, rings, kept["points"].astype(float), kept["toward_viewer"], float(kept["seconds"]))
    with tempfile.TemporaryDirectory() as folder:
        t0 = time.perf_counter()
        with open_rig(face_config(case, Path(folder), rings, bench)) as rig:
            result = run_scan(rig, "rings")
            parts = [result.cloud.points] + ([result.mesh.vertices] if result.mesh is not None else [])
            axis = -np.asarray(rig.projector_models[0].axis, float)
        seconds = time.perf_counter() - t0
    found = FaceScan(case, rings, np.concatenate(parts), axis / np.linalg.norm(axis), seconds)
    cache.mkdir(parents=True, exist_ok=True)
    kept = {"points": found.points.astype(np.float32), "toward_viewer": found.toward_viewer, "seconds": seconds}
    np.savez_compressed(stored, **kept)
    return found


def planned_rings(case: Case) -> dict[str, Any]:
    """The ring planner's count for `case`'s face (rig.plan, the adaptive scan's default tolerance),
    from a pilot scan with the adaptive scan's pilot codec."""
    with tempfile.TemporaryDirectory() as folder:
        config = face_config(case, Path(folder), None)
        with open_rig(config) as rig:
            pilot = run_scan(rig, config.scan.adaptive.pilot_codec)
            views = pilot_views(pilot, rig.camera_models, rig.projector_models)
            plan = plan_rings(views, config.scan.adaptive, method=config.scan.surface.interpolant)
    return {"rings": plan.rings, "tolerance_mm": plan.tolerance_mm, "face": case.name}
