"""API keys kept out of every line the daemon logs (rig.daemon.logs): in URLs (query values, names,
bare items, path segments), percent-encoded or not, in any message, traceback, and in the lines
uvicorn's access logger writes while serving."""

from __future__ import annotations

import asyncio
import contextlib
import http.client
import io
import logging
import socket
import threading
import time
from collections.abc import Iterator
from typing import Any
from urllib.parse import quote, quote_plus, unquote

import pytest
import uvicorn
from uvicorn.protocols.utils import get_path_with_query_string

from rig.daemon.logs import REDACTED, RedactQueryValues, RedactSecrets, install_redaction, redact_access_log

KEY = "0123456789abcdef" * 2
READ = "fedcba9876543210" * 2
ODD = "Sl/r1g+k3y&n=m?x%7e~*!"  # characters a URL encodes or splits on


# -- the log ------------------------------------------------------------------------------------------


@contextlib.contextmanager
def _log(*secrets: str, query_values: bool = True) -> Iterator[io.StringIO]:
    """What the daemon's logging writes, as cmd_serve and serve() set it up."""
    out = io.StringIO()
    handler = logging.StreamHandler(out)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    root, access = logging.getLogger(), logging.getLogger("uvicorn.access")
    saved = root.level, access.filters[:]
    root.addHandler(handler)
    root.setLevel(logging.INFO)
    try:
        install_redaction(secrets, [handler])
        if query_values:
            redact_access_log()
        yield out
    finally:
        root.removeHandler(handler)
        root.setLevel(saved[0])
        access.filters[:] = saved[1]


def _access(path: str, query: str = "") -> None:
    """An access record as uvicorn's h11 and httptools protocols log it."""
    scope: Any = {"path": unquote(path), "query_string": query.encode("ascii")}
    logging.getLogger("uvicorn.access").info(
        '%s - "%s %s HTTP/%s" %d', "127.0.0.1:5000", "GET", get_path_with_query_string(scope), "1.1", 200
    )


def _shows(text: str, key: str) -> bool:
    """Whether the key can be read in `text`, as it is or percent-decoded (once or twice)."""
    return any(key in t or key in t.replace("+", " ") for t in (text, unquote(text), unquote(unquote(text))))


def _forms(key: str) -> list[str]:
    everything = "".join(f"%{b:02x}" for b in key.encode())
    mixed = "".join(f"%{ord(c):02X}" if i % 2 else c for i, c in enumerate(key))
    return [key, quote(key), quote(key, safe=""), quote_plus(key), everything, everything.upper(), mixed]


@pytest.mark.parametrize("query_values", [True, False])
@pytest.mark.parametrize("key", [KEY, ODD])
def test_a_key_in_a_url_never_reaches_the_access_log(key: str, query_values: bool) -> None:
    encoded = quote(key, safe="")
    queries = [f"api_key={encoded}", f"{encoded}=1", encoded, f"a=1&{encoded}", f"a=1&{encoded}&b=2"]
    queries += [f"x={form}" for form in _forms(key) if form.isascii() and "&" not in form and "#" not in form]
    queries += [f"next={quote(quote(key, safe=''), safe='')}"]  # encoded twice
    with _log(key, query_values=query_values) as out:
        for query in queries:
            _access("/v1/scans", query)
        _access(f"/v1/scans/{encoded}/cloud.ply")  # a path segment
        _access(f"/v1/{encoded}", "a=1")
    lines = out.getvalue().splitlines()
    assert len(lines) == len(queries) + 2 and all(
        line.startswith("INFO uvicorn.access: 127.0.0.1:5000") for line in lines
    )
    leaking = [line for line in lines if _shows(line, key)]
    assert not leaking
    assert all(REDACTED in line for line in lines)
    if query_values:
        assert '"GET /v1/scans?a=REDACTED&REDACTED=REDACTED HTTP/1.1" 200' in lines[3]
    else:
        assert '"GET /v1/scans?a=1&REDACTED HTTP/1.1" 200' in lines[3]
    assert '"GET /v1/scans/REDACTED/cloud.ply HTTP/1.1" 200' in lines[-2]


def test_a_key_in_any_message_never_reaches_the_log() -> None:
    log = logging.getLogger("rig.daemon.somewhere")
    with _log(KEY, READ, query_values=False) as out:
        log.info("client sent %s", KEY)
        log.warning(f"read key {READ} and %s", "more")
        log.info("%r", {"key": quote_plus(ODD), "read": READ.upper()})  # READ.upper(): another string
        log.error("bad: %(key)s", {"key": f"/v1/{quote(KEY)}?{quote_plus(READ)}"})
        try:
            raise ValueError(f"cannot parse {KEY}")
        except ValueError:
            log.exception("failed with %s", quote(READ, safe=""))
    text = out.getvalue()
    assert not _shows(text, KEY) and not _shows(text, READ)
    assert "INFO rig.daemon.somewhere: client sent REDACTED" in text
    assert "read key REDACTED and more" in text
    assert "bad: /v1/REDACTED?REDACTED" in text
    assert READ.upper() in text  # only the keys themselves are hidden
    assert "ValueError: cannot parse REDACTED" in text and "failed with REDACTED" in text


def test_a_key_holding_url_delimiters_is_redacted_before_the_query_is_split() -> None:
    with _log(ODD) as out:
        _access("/v1/scans", ODD.replace("%", "%25"))  # sent as it is: a bare item split at & and =
    line = out.getvalue()
    assert not _shows(line, ODD) and "Sl/r1g" not in line and "n=m" not in line
    assert '"GET /v1/scans?REDACTED=REDACTED HTTP/1.1" 200' in line


def test_a_record_whose_arguments_do_not_fit_is_redacted_too() -> None:
    """Its handler would print its message and arguments as they are (logging.Handler.handleError)."""
    record = logging.LogRecord("rig.x", logging.INFO, __file__, 1, "%s %s from %s", (KEY,), None)
    assert RedactSecrets([KEY]).filter(record)
    assert record.getMessage() == "%s %s from %s ('REDACTED',)"


def test_redaction_is_replaced_not_stacked_and_nothing_without_keys() -> None:
    with _log(query_values=False) as out:
        logging.getLogger("rig.x").info("plain %s", "text")
        handler = logging.getLogger().handlers[-1]
        install_redaction([KEY], [handler])
        install_redaction([READ], [handler])
        logging.getLogger("rig.x").info("%s %s", KEY, READ)
    assert out.getvalue().splitlines() == ["INFO rig.x: plain text", f"INFO rig.x: {KEY} REDACTED"]


def test_the_access_log_still_writes_query_names_not_values() -> None:
    record = logging.LogRecord(
        "uvicorn.access", logging.INFO, __file__, 1, '%s - "%s %s HTTP/%s" %d',
        ("127.0.0.1:5000", "GET", "/v1/scans?token=s3cret&x=", "1.1", 200), None,
    )  # fmt: skip
    assert RedactQueryValues().filter(record)
    assert '"GET /v1/scans?token=REDACTED&x=REDACTED HTTP/1.1" 200' in record.getMessage()


def test_a_pathological_key_does_not_slow_the_log() -> None:
    key = "%25" * 200 + "%"
    text = "%25" * 5000
    start = time.monotonic()
    with _log(key, query_values=False) as out:
        logging.getLogger("rig.x").info("%s", text)
    assert time.monotonic() - start < 2 and out.getvalue()


# -- end to end: uvicorn serving, as the daemon runs it ---------------------------------------------


async def _not_found(scope: dict[str, Any], receive: Any, send: Any) -> None:
    await send({"type": "http.response.start", "status": 404, "headers": [(b"content-length", b"0")]})
    await send({"type": "http.response.body", "body": b""})


@pytest.mark.timeout(60)
def test_uvicorn_access_lines_do_not_show_the_key() -> None:
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(_not_found, log_config=None, lifespan="off"))
    targets = [
        f"/v1/scans?api_key={KEY}",
        f"/v1/scans?{KEY}",
        f"/v1/scans?a=1&{KEY}",
        f"/v1/scans?{KEY}=1",
        f"/v1/{KEY}/x",
        f"/v1/scans?k={quote(ODD, safe='')}",
        f"/v1/{quote(ODD, safe='')}",
        f"/v1/scans?k={''.join(f'%{b:02X}' for b in KEY.encode())}",
    ]
    with _log(KEY, ODD) as out:
        thread = threading.Thread(target=lambda: asyncio.run(server.serve(sockets=[sock])), daemon=True)
        thread.start()
        try:
            deadline = time.monotonic() + 30
            while not server.started and time.monotonic() < deadline:
                time.sleep(0.02)
            for target in targets:
                connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
                connection.request("GET", target)
                assert connection.getresponse().status == 404
                connection.close()
        finally:
            server.should_exit = True
            thread.join(30)
            sock.close()
    lines = [line for line in out.getvalue().splitlines() if "uvicorn.access" in line]
    assert len(lines) == len(targets), out.getvalue()
    assert not [line for line in lines if _shows(line, KEY) or _shows(line, ODD)]
    assert '"GET /v1/scans?a=REDACTED&REDACTED=REDACTED HTTP/1.1" 404' in lines[2]
    assert '"GET /v1/REDACTED/x HTTP/1.1" 404' in lines[4]
