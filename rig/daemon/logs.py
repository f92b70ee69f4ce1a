"""What the daemon's log may say: never an API key, and no query string values.

uvicorn's access log writes each request's path with its query string, and a client that puts
its API key in the URL (`?api_key=...`, `?KEY`, `/v1/KEY`) would leave the key in the journal.
Two filters keep it out:

- RedactQueryValues, on uvicorn's access logger: every query value becomes REDACTED (the names
  stay, for debugging);
- RedactSecrets, on the root logger's handlers (where every logger's records end, uvicorn's too:
  the daemon runs it with log_config=None): each key is replaced by REDACTED wherever it appears
  in a record's message, traceback or stack, as it is or percent-encoded (any mix of literal and
  %XX characters, hex digits in either case, encoded once or twice). A filter on a logger does not
  see the records of its child loggers; a filter on a handler sees every record it writes.
  On the access logger a RedactSecrets that keeps the record's arguments runs before
  RedactQueryValues, which would otherwise cut a key holding `&` or `=` into pieces that are
  no longer the key.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterable, Mapping
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
    """Install the redaction of query values on uvicorn's access logger (once)."""
    logger = logging.getLogger(ACCESS_LOGGER)
    if not any(isinstance(f, RedactQueryValues) for f in logger.filters):
        logger.addFilter(RedactQueryValues())


class RedactSecrets(logging.Filter):
    """Replaces each of `secrets` by REDACTED in the records it sees. By default their message is
    rendered (record.msg becomes the redacted text, record.args empty), their traceback and stack
    redacted too; with `keep_arguments`, only the record's text arguments are redacted, in place,
    for filters after this one that read them (RedactQueryValues)."""

    def __init__(self, secrets: Iterable[str], *, keep_arguments: bool = False) -> None:
        super().__init__()
        found = sorted({s for s in secrets if s}, key=len, reverse=True)  # the longest first: one may hold another
        self._pattern = re.compile("|".join(_any_encoding(s) for s in found)) if found else None
        self.keep_arguments = keep_arguments

    def redact(self, text: str) -> str:
        """`text` with every form of every secret replaced by REDACTED."""
        return text if self._pattern is None else self._pattern.sub(REDACTED, text)

    def filter(self, record: logging.LogRecord) -> bool:
        if self._pattern is None:
            return True
        if self.keep_arguments:
            self._redact_arguments(record)
            return True
        try:
            message = record.getMessage()
        except Exception:  # arguments that do not fit the format: the handler would print both
            message = f"{record.msg} {record.args!r}"
        record.msg, record.args = self.redact(message), ()
        if record.exc_info and not record.exc_text:
            record.exc_text = logging.Formatter().formatException(record.exc_info)
        if record.exc_text:
            record.exc_text = self.redact(record.exc_text)  # formatters print exc_text when it is set
        if record.stack_info:
            record.stack_info = self.redact(record.stack_info)
        return True

    def _redact_arguments(self, record: logging.LogRecord) -> None:
        args = record.args
        if isinstance(args, tuple):
            record.args = tuple(self.redact(a) if isinstance(a, str) else a for a in args)
        elif isinstance(args, Mapping):
            record.args = {k: self.redact(v) if isinstance(v, str) else v for k, v in args.items()}


def install_redaction(secrets: Iterable[str], handlers: Iterable[logging.Handler] | None = None) -> RedactSecrets:
    """Hide `secrets` in everything the root logger's handlers (or `handlers`) write, and in the
    arguments of uvicorn's access records before their query values are redacted. Call it once
    logging is configured: a handler added later is not covered. Replaces the RedactSecrets
    installed before. Returns the filter on the handlers."""
    redaction = RedactSecrets(secrets)
    for handler in logging.getLogger().handlers if handlers is None else handlers:
        _replace(handler, redaction)
    _replace(logging.getLogger(ACCESS_LOGGER), RedactSecrets(secrets, keep_arguments=True), first=True)
    return redaction


def _replace(filterer: logging.Filterer, redaction: RedactSecrets, first: bool = False) -> None:
    """`redaction` on `filterer` instead of any RedactSecrets there; `first`: before its other filters."""
    for old in [f for f in filterer.filters if isinstance(f, RedactSecrets)]:
        filterer.removeFilter(old)
    if first:
        filterer.filters.insert(0, redaction)
    else:
        filterer.addFilter(redaction)


def _any_encoding(secret: str) -> str:
    """A pattern matching `secret` with any of its characters percent-encoded (UTF-8, hex digits
    in either case, once or twice: %XX or %25XX) and spaces as `+`."""
    parts = []
    for char in secret:
        encoded = "".join(f"%(?:25)?{_hex(byte)}" for byte in char.encode("utf-8"))
        plus = "|\\+" if char == " " else ""
        parts.append(f"(?:{re.escape(char)}|{encoded}{plus})")
    return "".join(parts)


def _hex(byte: int) -> str:
    return "".join(f"[{d}{d.lower()}]" if d.isalpha() else d for d in f"{byte:02X}")
