"""The bench's geometry kept for the life of the process: the ray caster of a scene, what a camera
pose sees of it and how a projector lights that, found again by a digest of everything that
determines them. A process that opens the same simulated bench again (a daemon's next scan, a batch,
a test after another) then casts no ray it cast before: on the default bench that is about 1.7 s of
an open's 2.4 s gray scan. Content, not identity: equal scenes and poses built apart share an entry;
one that differs anywhere has its own. Kept arrays are read-only, so no caller can alter what
another will be given."""

from __future__ import annotations

import dataclasses
import hashlib
import os
import pickle
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from drivers.sim.raycast import RayCaster
from drivers.sim.scene import Scene

T = TypeVar("T")

# At most this many of each kind, and this many bytes of arrays in all, the least recently used
# dropped first: a 1280x1024 camera's view is about 100 MB (its truth search tree, once built, 60 MB
# more), its lighting by one projector about 40 MB, the default scene's caster 10 MB (a 5-million-
# face mesh's about 1 GB, which alone passes the budget and is not kept).
MAX_ENTRIES = {"caster": 2, "view": 4, "lighting": 4}
MAX_BYTES = 1 << 30
DISABLE = "SLRIG_SIM_MEMO"  # set to 0: every open casts its rays again (to measure a first open)

_kept: OrderedDict[tuple[str, bytes], tuple[Any, int]] = OrderedDict()
_lock = threading.Lock()


def digest(*parts: object) -> bytes | None:
    """A digest of `parts` by their pickled bytes (arrays by content); None where a part cannot be
    pickled (a texture of the caller's own making): that geometry is not kept."""
    h = hashlib.blake2b(digest_size=20)
    try:
        for part in parts:
            h.update(pickle.dumps(part, protocol=pickle.HIGHEST_PROTOCOL))
    except (pickle.PicklingError, TypeError, AttributeError):
        return None
    return h.digest()


def device_key(device: Any) -> tuple[object, ...] | None:
    """What fixes a device's rays: its kind, size, intrinsics, pose, distortion and projection (not
    the rays it caches); None for a device that does not show them (its geometry is not kept)."""
    try:
        return (
            type(device).__qualname__,
            device.width,
            device.height,
            device.K,
            device.R,
            device.t,
            device.dist,
            device.projection,
        )
    except AttributeError:
        return None


def keyed(*parts: object) -> bytes | None:
    """digest(*parts), None where any part is None (unknown: not kept)."""
    return None if any(part is None for part in parts) else digest(*parts)


def remembered(kind: str, key: bytes | None, compute: Callable[[], T]) -> T:
    """The `kind` entry kept under `key`, else `compute()` kept there; its arrays read-only either
    way. Computed outside the lock: two threads asking at once both compute, and one is kept."""
    if key is None or os.environ.get(DISABLE) == "0":
        return _read_only(compute())
    with _lock:
        if (kind, key) in _kept:
            _kept.move_to_end((kind, key))
            return _kept[kind, key][0]
    value = _read_only(compute())
    size = _nbytes(value)
    with _lock:
        _kept[kind, key] = (value, size)
        _kept.move_to_end((kind, key))
        _drop_beyond_budget(kind)
    return value


def _drop_beyond_budget(kind: str) -> None:
    """Drop the least recently used entries of `kind` past its count, then of any kind past the
    byte budget (the newest entry too, if it alone passes it)."""
    same = [k for k in _kept if k[0] == kind]
    for stale in same[: max(0, len(same) - MAX_ENTRIES[kind])]:
        del _kept[stale]
    while _kept and sum(size for _, size in _kept.values()) > MAX_BYTES:
        _kept.popitem(last=False)


def scene_caster(scene: Scene) -> tuple[bytes | None, RayCaster]:
    """The scene's digest (None if it cannot be taken) and its ray caster, built once a process."""
    key = digest(scene)
    return key, remembered("caster", key, lambda: RayCaster(scene.vertices, scene.faces))


def forget() -> None:
    """Drop every entry (for a test that measures a first open)."""
    with _lock:
        _kept.clear()


def _arrays(value: object) -> list[np.ndarray]:
    """The arrays an entry holds in its fields (a dataclass's, or an object's attributes)."""
    fields = vars(value) if hasattr(value, "__dict__") else {}
    return [a for a in fields.values() if isinstance(a, np.ndarray)]


def _read_only(value: T) -> T:
    if dataclasses.is_dataclass(value):
        for array in _arrays(value):
            array.flags.writeable = False
    return value


def _nbytes(value: object) -> int:
    return sum(a.nbytes for a in _arrays(value))
