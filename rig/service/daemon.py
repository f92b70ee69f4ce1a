"""`slrig serve`: the job service behind the REST API on uvicorn, with systemd notification.

READY=1 goes out once the socket is bound; WATCHDOG=1 at half the watchdog interval, from the
event loop and only while the job worker is healthy (a wedged driver stops the pings and systemd
restarts the service). On SIGTERM or SIGINT the running job is cancelled at once (projectors
dark), event streams end, and the service stops within its shutdown timeout.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import signal
from collections.abc import Iterator
from pathlib import Path

import uvicorn

from rig.api.app import create_app
from rig.api.security import ApiSettings, check_key_strength, is_loopback
from rig.config import RigConfig
from rig.errors import ConfigError
from rig.service.runner import JobService
from rig.service.sdnotify import Notifier

log = logging.getLogger(__name__)

KEY_ENV = "SLRIG_API_KEY"
KEY_CREDENTIAL = "slrig-api-key"  # systemd LoadCredential= name


def load_api_key(key_file: Path | None) -> str | None:
    """From --api-key-file, the systemd credential, or $SLRIG_API_KEY, in that order."""
    source, key = None, None
    credentials = os.environ.get("CREDENTIALS_DIRECTORY")
    if key_file is not None:
        source = "--api-key-file"
        try:
            key = key_file.read_text().strip()
        except OSError as exc:
            raise ConfigError(source, [f"--api-key-file: cannot read {key_file}: {exc.strerror}"]) from None
    elif credentials and (Path(credentials) / KEY_CREDENTIAL).is_file():
        source, key = "credential", (Path(credentials) / KEY_CREDENTIAL).read_text().strip()
    elif os.environ.get(KEY_ENV):
        source, key = KEY_ENV, os.environ[KEY_ENV].strip()
    if key is not None:
        problem = check_key_strength(key)
        if problem:
            raise ConfigError(source or "api key", [f"{source}: the API key {problem}"])
    return key


def api_settings(config: RigConfig, host: str, api_key: str | None) -> ApiSettings:
    loopback = is_loopback(host)
    if not loopback and api_key is None:
        raise ConfigError(
            "--host",
            [f"--host: listening on {host} (beyond loopback) needs an API key: set {KEY_ENV} or --api-key-file"],
        )
    hosts = ["127.0.0.1", "localhost", "::1", "[::1]", *config.service.allowed_hosts]
    if not loopback:
        hosts = [*hosts, host] if config.service.allowed_hosts else ["*"]  # the key guards every request
    return ApiSettings(
        api_key=api_key,
        protect_reads=not loopback,
        max_body_bytes=config.service.max_body_bytes,
        cors_origins=tuple(config.service.cors_origins),
        allowed_hosts=tuple(hosts),
    )


class _Server(uvicorn.Server):
    """uvicorn re-raises a caught SIGTERM once it has served, which would end the process before
    the job service stops; the daemon handles the signals itself (in _run)."""

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        yield


def serve(config: RigConfig, host: str, port: int, api_key: str | None) -> int:
    settings = api_settings(config, host, api_key)
    service = JobService(config, config.service.max_queue, config.service.health_stale_s)
    notifier = Notifier()
    server: uvicorn.Server | None = None

    def stopping() -> bool:
        return service.stopping or (server is not None and server.should_exit)

    app = create_app(service, settings, stopping)
    uv_config = uvicorn.Config(
        app,
        host=host,
        port=port,
        log_config=None,  # our logging: stderr, read by journald
        timeout_graceful_shutdown=2,
        limit_concurrency=128,
        timeout_keep_alive=5,
        lifespan="off",
    )
    server = _Server(uv_config)
    service.start()
    log.info("slrig serving rig %r from %s (key %s)", config.name, config.output.data_dir, "set" if api_key else "off")
    try:
        asyncio.run(_run(server, service, notifier))
    except SystemExit as exc:  # uvicorn could not start (it logged why: port in use, bad address)
        log.error("could not serve on %s:%d", host, port)
        return 1 if exc.code in (None, 0) else int(exc.code) if isinstance(exc.code, int) else 1
    finally:
        notifier.notify("STOPPING=1")
        service.shutdown(config.service.shutdown_timeout_s)
        log.info("slrig stopped")
    return 0


async def _run(server: uvicorn.Server, service: JobService, notifier: Notifier) -> None:
    loop = asyncio.get_running_loop()

    def on_signal(signum: int) -> None:
        log.info("%s received", signal.Signals(signum).name)
        if server.should_exit:
            server.force_exit = True  # a second signal: do not wait for open connections
        server.should_exit = True

    for signum in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(signum, on_signal, signum)
    serving = asyncio.create_task(server.serve())
    while not server.started and not serving.done():
        await asyncio.sleep(0.02)
    if serving.done():  # could not bind: uvicorn logged why (and raised SystemExit)
        await serving
        raise SystemExit(1)
    address = server.servers[0].sockets[0].getsockname()
    log.info("listening on http://%s:%d", address[0], address[1])
    notifier.notify("READY=1", f"STATUS=serving on {address[0]}:{address[1]}")
    interval = notifier.watchdog_interval_s
    next_ping = 0.0
    while not serving.done():
        if server.should_exit and not service.stopping:
            log.info("stopping: cancelling the running job")
            service.begin_stop()  # at once, while uvicorn closes connections
        if interval is not None and loop.time() >= next_ping:
            next_ping = loop.time() + interval
            if service.healthy():
                notifier.notify("WATCHDOG=1")
            else:
                log.error("job worker unhealthy: watchdog pings withheld")
                notifier.notify("STATUS=job worker unhealthy")
        await asyncio.sleep(0.05)
    await serving
