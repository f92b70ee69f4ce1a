"""`slrig doctor` and `slrig devices`: what is attached to this machine, whether a config fits
it, and the measured display latency of each projector."""

from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "check": "checks",
    "describe": "inventory",
    "machine_inventory": "inventory",
    "measure_latency": "latency",
    "store_latencies": "latency",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "check",
    "describe",
    "machine_inventory",
    "measure_latency",
    "store_latencies",
]
