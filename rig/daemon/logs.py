"""What the daemon's log may say: uvicorn's access log writes each request's path with its query
string, and a client that puts its API key in the query string (`?api_key=...`) would leave the key
in the journal. Query strings are logged with every value replaced, so the names stay for debugging
and no value is ever written."""

from __future__ import annotations

import logging
from urllib.parse import parse_qsl, urlencode

ACCESS_LOGGER = "uvicorn.access"
REDACTED = "REDACTED"


class RedactQueryValues(logging.Filter):
    """Replaces the values of a uvicorn access record's query string (its third argument: the path
    with the query) by REDACTED."""

    def filter(self, record: logging.LogRecord) -> bool:
        args = record.args
        if isinstance(args, tuple) and len(args) >= 3 and isinstance(args[2], str) and "?" in args[2]:
            path, _, query = args[2].partition("?")
            names = [(name, REDACTED) for name, _ in parse_qsl(query, keep_blank_values=True)]
            record.args = (*args[:2], f"{path}?{urlencode(names)}" if names else path, *args[3:])
        return True


def redact_access_log() -> None:
    """Install the redaction on uvicorn's access logger (once)."""
    logger = logging.getLogger(ACCESS_LOGGER)
    if not any(isinstance(f, RedactQueryValues) for f in logger.filters):
        logger.addFilter(RedactQueryValues())
