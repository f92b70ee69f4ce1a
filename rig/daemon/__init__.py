"""The daemon process: the job service behind the REST API under uvicorn, the API key, and
systemd notification (ready, watchdog, stopping)."""

from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "install_redaction": "logs",
    "load_api_keys": "keys",
    "serve": "server",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "install_redaction",
    "load_api_keys",
    "serve",
]
