"""The REST API of `slrig serve` (FastAPI), versioned under /v1."""

from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "ApiSettings": "security",
    "check_key_strength": "security",
    "create_app": "app",
    "header_key": "security",
    "is_loopback": "security",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "ApiSettings",
    "check_key_strength",
    "create_app",
    "header_key",
    "is_loopback",
]
