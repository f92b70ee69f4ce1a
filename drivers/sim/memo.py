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
import pickle
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from drivers.sim.raycast import RayCaster
from drivers.sim.scene import Scene

T = TypeVar("T")

# Entries kept, the least recently used dropped first: a 1280x1024 camera's view with its truth
# search tree is about 160 MB, its lighting by one projector about 40 MB.
MAX_ENTRIES = {"caster": 4, "view": 4, "lighting": 4}

_kept: dict[str, OrderedDict[bytes, Any]] = {kind: OrderedDict() for kind in MAX_ENTRIES}
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


def device_key(device: Any) -> tuple[object, ...]:
    """What fixes a device's rays: its size, intrinsics, pose, distortion and projection (not the
    rays it caches)."""
    return (device.width, device.height, device.K, device.R, device.t, device.dist, device.projection)


def remembered(kind: str, key: bytes | None, compute: Callable[[], T]) -> T:
    """The `kind` entry kept under `key`, else `compute()` kept there (its arrays made read-only).
    Computed outside the lock: two threads asking at once both compute, and one is kept."""
    if key is None:
        return compute()
    with _lock:
        entries = _kept[kind]
        if key in entries:
            entries.move_to_end(key)
            return entries[key]
    value = _read_only(compute())
    with _lock:
        entries[key] = value
        while len(entries) > MAX_ENTRIES[kind]:
            entries.popitem(last=False)
    return value


def scene_caster(scene: Scene) -> tuple[bytes | None, RayCaster]:
    """The scene's digest (None if it cannot be taken) and its ray caster, built once a process."""
    key = digest(scene)
    return key, remembered("caster", key, lambda: RayCaster(scene.vertices, scene.faces))


def forget() -> None:
    """Drop every entry (for a test that measures a first open)."""
    with _lock:
        for entries in _kept.values():
            entries.clear()


def _read_only(value: T) -> T:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        for field in dataclasses.fields(value):
            array = getattr(value, field.name)
            if isinstance(array, np.ndarray):
                array.flags.writeable = False
    return value
