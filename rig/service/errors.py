"""Errors of the job service; the API maps each to an HTTP status."""

from __future__ import annotations

from rig.errors import SlrigError


class JobNotFoundError(SlrigError):
    """Raised when a job id names no job (HTTP 404)."""


class QueueFullError(SlrigError):
    """Raised when a job is submitted while the queue holds its maximum (HTTP 429)."""


class JobConflictError(SlrigError):
    """Raised when an action does not fit the job's state: deleting a running scan, downloading
    from one not done, reprocessing one without frames (HTTP 409)."""


class IllegalTransitionError(SlrigError):
    """Raised when a job record would move between states the state machine does not allow: a
    programming error, or a damaged record whose stored state this version does not know (HTTP
    409: it can only be deleted)."""


class JobCancelledError(SlrigError):
    """Raised inside a running job when it has been cancelled or the daemon is stopping."""


class StorageFullError(SlrigError):
    """Raised when the data directory cannot take what is asked: too little free space for a
    scan's expected size, or a job database that cannot be written (a full disk, an I/O error).
    Nothing is changed (HTTP 507)."""


class TooManyOpenError(SlrigError):
    """Raised when a long response (an event stream, a file download) is asked for while every
    slot of its kind, overall or for the client's address, is taken (HTTP 429, Retry-After)."""


class ServiceStoppingError(SlrigError):
    """Raised when a job is submitted while the daemon shuts down (HTTP 503)."""


class ImportNotFoundError(SlrigError):
    """Raised when an imports folder named by a request is not there (HTTP 404)."""


class ImportTooLargeError(SlrigError):
    """Raised when an upload would make its imports folder larger than service.max_import_bytes;
    nothing is written (HTTP 413)."""


class ImportRefusedError(SlrigError):
    """Raised when an upload or a reconstruction request names a file that is refused or missing:
    a name that is not a plain file name, an unknown suffix, a full folder, an empty body, an
    image larger than allowed by its header (HTTP 422)."""


class SetupRefusedError(SlrigError):
    """Raised when an aim or camera-settings request names what this rig does not have (a
    projector, camera or codec pattern) or a driver refuses a value (out of its range, no gain
    control); nothing changed."""


class MigrationError(SlrigError):
    """Raised when a data directory cannot be moved (`slrig store migrate`): not a data directory, a
    target that exists or lies on another file system; nothing was moved."""


class RemoteUnavailableError(SlrigError):
    """Raised when a job is handed to `compute.scheduler` and no Dask scheduler answers there (or
    Dask is not installed); the job fails with this reason, and the daemon's worker goes on."""
