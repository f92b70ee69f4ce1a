"""`slrig serve`: the job service behind the REST API on uvicorn, with systemd notification.

READY=1 goes out once the socket is bound; WATCHDOG=1 at half the watchdog interval, from the
event loop and only while the job worker is healthy (a wedged driver stops the pings and systemd
restarts the service). On SIGTERM or SIGINT the running job is cancelled at once (projectors
dark), event streams end, responses still in flight are cut, and the process ends: within a
second in every state, a stalled driver included (rig.service.stopping).
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import os
import resource
import signal
import socket
from collections.abc import Iterator

import uvicorn

from rig.api import ApiSettings, create_app, is_loopback
from rig.config import RigConfig
from rig.daemon.connections import guarded_protocol
from rig.daemon.logs import redact_access_log
from rig.daemon.sdnotify import Notifier
from rig.errors import ConfigError, UsageError
from rig.service import JobService

log = logging.getLogger(__name__)

WILDCARDS = ("0.0.0.0", "::", "[::]")


def api_settings(config: RigConfig, host: str, api_key: str, read_key: str | None = None) -> ApiSettings:
    """Mutations need the API key. Reads need a key (either) as service.read_access says: by
    default open on loopback and protected beyond, where Host headers must also name this machine
    as clients reach it."""
    loopback = is_loopback(host)
    hosts = ["127.0.0.1", "localhost", "::1", "[::1]", *config.service.allowed_hosts]
    if not loopback:
        if host in WILDCARDS and not config.service.allowed_hosts:
            raise ConfigError(
                "service.allowed_hosts",
                [
                    f"service.allowed_hosts: listening on all addresses ({host}) needs the names or "
                    "addresses clients use in the Host header, e.g. [scanner.lab.example, 192.0.2.7]"
                ],
            )
        hosts.append(host)
    access = config.service.read_access
    protect_reads = access == "key" or (access == "auto" and not loopback)
    if not loopback and not protect_reads:
        log.warning("service.read_access is open on %s: anyone who reaches the port can read every scan", host)
    return ApiSettings(
        api_key=api_key,
        protect_reads=protect_reads,
        read_key=read_key,
        max_downloads=config.service.max_downloads,
        max_downloads_per_client=config.service.max_downloads_per_client,
        max_body_bytes=config.service.max_body_bytes,
        cors_origins=tuple(config.service.cors_origins),
        allowed_hosts=tuple(hosts),
        body_stall_s=config.service.body_stall_s,
    )


def bind(host: str, port: int) -> socket.socket:
    """The listening socket, bound before anything else starts; UsageError naming --port when
    another program holds it, --host when it is not an address of this machine."""
    try:
        found = socket.getaddrinfo(host.strip("[]") or None, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
        family, kind, proto, _, address = min(found, key=lambda a: a[0] != socket.AF_INET)  # IPv4 first, as uvicorn
    except socket.gaierror as exc:
        raise UsageError(f"--host {host}: not an address this machine can listen on ({exc.strerror})") from None
    sock = socket.socket(family, kind, proto)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # a restart need not wait out TIME_WAIT
    try:
        sock.bind(address)
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EACCES and port < 1024:
            raise UsageError(f"--port {port}: ports below 1024 need privileges (CAP_NET_BIND_SERVICE)") from None
        if exc.errno == errno.EADDRINUSE:
            raise UsageError(
                f"--port {port}: {host}:{port} is in use by another program (another slrig?); "
                "stop it or choose another --port"
            ) from None
        raise UsageError(f"--host {host}: cannot listen there ({exc.strerror})") from None
    return sock


def _descriptors_for(max_connections: int) -> int:
    """Raise the soft limit of open files to hold `max_connections` and the rest of the daemon;
    where the hard limit is lower, the connections that fit it (with a warning)."""
    spare = 256  # devices, the database, logs, frames being read
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    needed = max_connections + spare
    if hard != resource.RLIM_INFINITY and hard < needed:
        fitting = max(16, hard - spare)
        log.warning("open files are limited to %d: serving at most %d connections (LimitNOFILE=)", hard, fitting)
        needed, max_connections = hard, fitting
    if soft != resource.RLIM_INFINITY and soft < needed:
        resource.setrlimit(resource.RLIMIT_NOFILE, (needed, hard))
    return max_connections


class _Server(uvicorn.Server):
    """uvicorn re-raises a caught SIGTERM once it has served, which would end the process before
    the job service stops; the daemon handles the signals itself (in _run). And it stops at once:
    uvicorn looks at should_exit every 0.1 s, this server also as soon as `exit_now` is set, and
    responses still in flight HTTP_GRACE_S after the stop began are cut (event streams end by
    themselves; a download to a client that reads slowly would otherwise hold the exit)."""

    HTTP_GRACE_S = 0.3  # a short request in flight finishes in milliseconds

    def __init__(self, config: uvicorn.Config) -> None:
        super().__init__(config)
        self.exit_now = asyncio.Event()

    @contextlib.contextmanager
    def capture_signals(self) -> Iterator[None]:
        yield

    async def main_loop(self) -> None:
        """uvicorn's: a tick every 0.1 s (the date header, should_exit), but woken to stop."""
        counter = 0
        while not await self.on_tick(counter):
            counter = (counter + 1) % 864000
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.exit_now.wait(), 0.1)

    def stop(self, force: bool = False) -> None:
        """Stop serving now; `force`: cut the responses in flight too."""
        self.force_exit = self.force_exit or force
        self.should_exit = True
        self.exit_now.set()


def serve(config: RigConfig, host: str, port: int, api_key: str, read_key: str | None = None) -> int:
    """Serve until SIGTERM or SIGINT, then stop and end the process (os._exit(0)): the job
    service has darkened the projectors and recorded its jobs by then, and the interpreter's own
    teardown took 0.2-0.45 s (numba, scipy, trimesh) and would wait for a worker still inside a
    computation. Returns only when uvicorn could not start (its exit code)."""
    settings = api_settings(config, host, api_key, read_key)
    sock = bind(host, port)
    service = JobService(config, config.service.max_queue, config.service.health_stale_s)
    notifier = Notifier()
    server: _Server | None = None

    def stopping() -> bool:
        return service.stopping or (server is not None and server.should_exit)

    app = create_app(service, settings, stopping)
    max_connections = _descriptors_for(config.service.max_connections)
    uv_config = uvicorn.Config(
        app,
        host=host,
        port=port,
        log_config=None,  # our logging: stderr, read by journald
        timeout_graceful_shutdown=2,  # a backstop: _run cuts responses after _Server.HTTP_GRACE_S
        http=guarded_protocol(  # no concurrency cap: connections are bounded in rig.daemon.connections
            config.service.header_timeout_s,
            max_connections,
            config.service.send_timeout_s,
            config.service.min_send_rate,
            keys=tuple(key for key in (settings.api_key, settings.read_key) if key),
        ),
        timeout_keep_alive=5,
        lifespan="off",
    )
    server = _Server(uv_config)
    redact_access_log()  # a key in a query string never reaches the journal
    service.start()
    log.info("slrig serving rig %r from %s", config.name, config.output.data_dir)
    try:
        asyncio.run(_run(server, sock, service, notifier, config.service.shutdown_timeout_s))
    except KeyboardInterrupt:  # a signal between the event loop's end and here
        pass
    except SystemExit as exc:  # uvicorn could not start (it logged why: port in use, bad address)
        log.error("could not serve on %s:%d", host, port)
        return 1 if exc.code in (None, 0) else int(exc.code) if isinstance(exc.code, int) else 1
    finally:
        for signum in (signal.SIGTERM, signal.SIGINT):  # a second signal must not cut the shutdown short
            signal.signal(signum, signal.SIG_IGN)
        service.shutdown(config.service.shutdown_timeout_s, wait_for_worker=False)  # done in _run, unless it failed
        log.info("slrig stopped")
    logging.shutdown()  # flushed: the journal has every line
    os._exit(0)


async def _run(
    server: _Server, sock: socket.socket, service: JobService, notifier: Notifier, shutdown_timeout_s: float
) -> None:
    """Serve, ping the watchdog, and on a signal stop the job service beside uvicorn's shutdown."""
    loop = asyncio.get_running_loop()
    shutting_down: list[asyncio.Future[None]] = []  # the job service's shutdown, once begun

    def stop() -> None:
        if not shutting_down:
            log.info("stopping: cancelling the running job")
            notifier.notify("STOPPING=1")
            service.begin_stop()  # at once: the worker's waits are cut, it darkens and records
            shutting_down.append(loop.run_in_executor(None, service.shutdown, shutdown_timeout_s, False))
            loop.call_later(_Server.HTTP_GRACE_S, server.stop, True)
        server.stop()

    def on_signal(signum: int) -> None:
        log.info("%s received", signal.Signals(signum).name)
        server.stop(force=server.should_exit)  # a second signal: do not wait for open connections
        stop()

    for signum in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(signum, on_signal, signum)
    serving = asyncio.create_task(server.serve(sockets=[sock]))
    while not server.started and not serving.done():
        await asyncio.sleep(0.02)
    if serving.done() and not server.started and not shutting_down:  # could not bind: uvicorn said why
        await serving
        raise SystemExit(1)
    listening = [s for srv in server.servers for s in srv.sockets] if not server.should_exit else []
    if listening:  # (none: a signal in the moment after the start has stopped it already)
        address = listening[0].getsockname()
        log.info("listening on http://%s:%d (the console: open it in a browser; the API: /v1, /docs)", *address[:2])
        notifier.notify("READY=1", f"STATUS=serving on {address[0]}:{address[1]}")
    interval = notifier.watchdog_interval_s
    next_ping = 0.0
    while not serving.done():
        if server.should_exit:
            stop()
        if interval is not None and loop.time() >= next_ping and not service.stopping:
            next_ping = loop.time() + interval
            if service.healthy():
                notifier.notify("WATCHDOG=1")
            else:
                log.error("job worker unhealthy: watchdog pings withheld")
                notifier.notify("STATUS=job worker unhealthy")
        await asyncio.wait({serving}, timeout=0.05)
    await serving
    for shutdown in shutting_down:
        await shutdown
