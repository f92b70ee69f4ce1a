"""The OAK worker: one camera behind depthai, in its own process (depthai can abort the process it
runs in). Commands are JSON lines on stdin; each answer is a JSON line on stdout, a frame's
followed by its raw bytes:

    {"cmd": "open", "backend": "depthai"|"fake", ...settings}   -> {"ok": true}
    {"cmd": "exposure", "exposure_us": N, "iso": N}             -> {"ok": true}
    {"cmd": "frame", "timeout_s": S}  -> {"ok": true, "sequence", "timestamp", "exposure_us", "shape"} + bytes
    {"cmd": "drain"}                  -> {"ok": true, "dropped": N}
    {"cmd": "close"}                  -> {"ok": true}, then exit
A failure answers {"ok": false, "kind": ..., "error": ...}; end of input closes and exits.
"""

from __future__ import annotations

import json
import os
import sys
from typing import Any

from drivers.oak.backends import BACKENDS, BackendError, OakSettings


def _answer(out: Any, message: dict[str, Any], payload: bytes = b"") -> None:
    out.write(json.dumps(message).encode() + b"\n" + payload)
    out.flush()


def _protocol_stream() -> Any:
    """The answers' own channel: the original stdout. Everything else that writes to file
    descriptor 1 (depthai's native logger does) is sent to stderr instead."""
    sys.stdout.flush()
    answers = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    return answers


def main() -> int:
    out = _protocol_stream()
    backend = None
    for line in sys.stdin.buffer:
        request = json.loads(line)
        command = request.pop("cmd")
        try:
            if command == "open":
                backend = BACKENDS[request.pop("backend")](OakSettings(**request))
                _answer(out, {"ok": True})
            elif backend is None:
                _answer(out, {"ok": False, "kind": "protocol", "error": "not open"})
            elif command == "exposure":
                backend.set_exposure(int(request["exposure_us"]), int(request["iso"]))
                _answer(out, {"ok": True})
            elif command == "frame":
                image, sequence, stamp, exposure = backend.frame(float(request["timeout_s"]))
                data = image.tobytes()
                _answer(
                    out,
                    {
                        "ok": True,
                        "sequence": sequence,
                        "timestamp": stamp,
                        "exposure_us": exposure,
                        "shape": list(image.shape),
                        "size": len(data),
                    },
                    data,
                )
            elif command == "drain":
                _answer(out, {"ok": True, "dropped": backend.drain()})
            elif command == "close":
                backend.close()
                _answer(out, {"ok": True})
                return 0
        except BackendError as exc:
            _answer(out, {"ok": False, "kind": exc.kind, "error": str(exc)})
    if backend is not None:
        backend.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
