"""Errors of slrig itself (device faults are in drivers.errors)."""

from __future__ import annotations


class SlrigError(Exception):
    """Base of slrig's own errors; the CLI prints their message and exits with code 2."""


class ConfigError(SlrigError):
    """Raised when a rig description is invalid; `problems` lists every error, each naming its
    field (`cameras[0].resolution: ...`)."""

    def __init__(self, source: str, problems: list[str]) -> None:
        self.source = source
        self.problems = problems
        super().__init__(f"invalid config {source}:\n" + "\n".join(f"  {p}" for p in problems))


class UsageError(SlrigError):
    """Raised when the command line asks for what cannot be done, though every input is valid: an
    output directory that exists already. The CLI exits with code 2."""


class UnknownCodecError(SlrigError):
    """Raised when a codec name is not in the registry; the message lists the known names."""


class SceneError(SlrigError):
    """Raised when a simulated scene cannot be built (missing or unreadable mesh file)."""


class DecodeError(SlrigError):
    """Raised when captured frames do not fit the codec (wrong count or shape)."""


class PatternSpecError(SlrigError):
    """Raised when a pattern description (YAML) cannot be read or does not hold; `problems` lists
    every error, each naming its field."""

    def __init__(self, source: str, problems: list[str]) -> None:
        self.source = source
        self.problems = problems
        super().__init__(f"invalid pattern description {source}:\n" + "\n".join(f"  {p}" for p in problems))


class FramesError(SlrigError):
    """Raised when a folder of frames does not hold what its description lists: a missing, extra,
    unreadable or differently sized frame, or another number of frames; or when an image's header
    (rig.store.image_header) is unknown or cut short, or gives a size over the limit or not the
    camera's, which is found before the image is decoded. Nothing is written."""


class ScanError(SlrigError):
    """Raised when a scan fails; the projectors are dark when it propagates."""


class CaptureFaultError(ScanError):
    """Raised when the rig delivers frames a scan cannot use: a stale (repeated) frame, frames
    dropped within a sequence, a missed trigger, frames exposed before the pattern was lit. A
    fault of the rig, reported by `/v1/rig` like a device fault."""


class StoreError(SlrigError):
    """Raised when a scan cannot be stored: the target exists already, or the disk refuses."""


class CalibrationError(SlrigError):
    """Raised when calibration cannot produce a result: no board found, too few views, images that
    do not fit the rig. Nothing is written when it is raised."""


class PlanError(SlrigError):
    """Raised when rings cannot be planned: a tolerance that is not positive, a pilot scan with no
    points, or a surface the rings do not reach. The message names the input and the reason."""


class RecognitionError(SlrigError):
    """Raised when a scan cannot be described or identified: too little surface around its
    reference point, descriptor settings that differ from the gallery's, an empty gallery."""


class GalleryError(RecognitionError):
    """Raised when the recognition gallery refuses a change or cannot be read: a label that is not
    a plain name, a scan already in it, an entry that is not there, a file that is not a gallery or
    is from a newer slrig. The file is left as it was."""


class GalleryFileError(GalleryError):
    """Raised when the gallery file cannot be used: not a gallery, from a newer slrig, unreadable.
    It is left as it is."""


class GalleryEntryNotFoundError(GalleryError):
    """Raised when a gallery entry asked for by its id is not there."""
