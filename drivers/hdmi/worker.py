"""The display worker: a process that owns one display output and shows full-screen patterns.

Run as `python -m drivers.hdmi.worker WIDTH HEIGHT DISPLAY`; SDL_VIDEODRIVER chooses the output
(kmsdrm on a bench with no desktop, x11/wayland under one, offscreen in CI). It reads commands on
stdin and answers each on stdout:

    S <length>\\n<length bytes: uint8 pattern, HEIGHT x WIDTH>   show it      -> P <monotonic s> <checksum>\\n
    C <length>\\n<length bytes: uint8 RGB, HEIGHT x WIDTH x 3>   show it      -> P <monotonic s> <checksum>\\n
    D\\n                                                          dark         -> P <monotonic s> <checksum>\\n
    Q\\n                                                          dark, exit

The presentation time is taken right after the buffer flip. The checksum (CRC-32) is of the red
channel as read back from the screen for S and D, of the whole RGB image for C. On end of input (the parent died), on
SIGTERM, and on any error the screen is made black before the worker exits. Kept free of slrig's
other modules so it starts fast and can run under its own systemd unit.
"""

from __future__ import annotations

import os
import signal
import sys
import time
import zlib
from typing import Any

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")


def main(argv: list[str]) -> int:
    import pygame

    width, height, display = int(argv[0]), int(argv[1]), int(argv[2]) if len(argv) > 2 else 0
    pygame.display.init()
    flags = 0 if os.environ.get("SDL_VIDEODRIVER") == "offscreen" else pygame.FULLSCREEN | pygame.NOFRAME
    screen = pygame.display.set_mode((width, height), flags, display=display)
    pygame.mouse.set_visible(False)

    def black() -> None:
        screen.fill((0, 0, 0))
        pygame.display.flip()

    def stop(*_: object) -> None:
        black()
        pygame.display.quit()
        sys.exit(0)

    signal.signal(signal.SIGTERM, stop)
    black()
    sys.stdout.flush()
    out = os.fdopen(os.dup(1), "wb")  # the answers' channel; anything else printed goes to stderr
    os.dup2(2, 1)
    stdin = sys.stdin.buffer
    out.write(b"R\n")  # ready
    out.flush()
    try:
        while True:
            line = stdin.readline()
            if not line or line.startswith(b"Q"):
                break
            if line.startswith((b"S", b"C")):
                answer = _present(screen, line, stdin, width, height)
                if answer is None:
                    break
                out.write(answer)
            elif line.startswith(b"D"):
                black()
                checksum = zlib.crc32(pygame.surfarray.array_red(screen).T.tobytes())
                out.write(f"P {time.monotonic():.6f} {checksum}\n".encode())
            out.flush()
            pygame.event.pump()  # keep the window responsive
    finally:
        black()
        pygame.display.quit()
    return 0


def _present(screen: Any, line: bytes, stdin: Any, width: int, height: int) -> bytes | None:
    """Show one image that follows `S <size>` (grey) or `C <size>` (RGB) on stdin; the answer
    `P <time shown> <crc32 of what the screen holds>`, or None for a malformed request."""
    import numpy as np
    import pygame

    colour = line.startswith(b"C")
    size = int(line.split()[1])
    data = stdin.read(size)
    if len(data) != size or size != width * height * (3 if colour else 1):
        return None
    if colour:
        rgb = np.frombuffer(data, dtype=np.uint8).reshape(height, width, 3).transpose(1, 0, 2)
    else:
        pattern = np.frombuffer(data, dtype=np.uint8).reshape(height, width)
        rgb = np.repeat(pattern.T[:, :, None], 3, axis=2)  # surfarray is (x, y)
    pygame.surfarray.blit_array(screen, rgb)
    pygame.display.flip()
    shown = time.monotonic()
    if colour:
        checksum = zlib.crc32(pygame.surfarray.array3d(screen).transpose(1, 0, 2).tobytes())
    else:
        checksum = zlib.crc32(pygame.surfarray.array_red(screen).T.tobytes())
    return f"P {shown:.6f} {checksum}\n".encode()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
