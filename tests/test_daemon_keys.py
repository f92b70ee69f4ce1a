"""The daemon's API keys (rig.daemon.keys): what a key file, credential or environment variable
may hold, the read-only key, and `slrig serve` refusing an unfit key (exit 2). Keys kept out of
the log: tests/test_daemon_log_redaction.py."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from rig.daemon.keys import (
    GENERATED_KEY,
    KEY_CREDENTIAL,
    KEY_ENV,
    MAX_KEY_BYTES,
    READ_KEY_CREDENTIAL,
    READ_KEY_ENV,
    ApiKeys,
    load_api_key,
    load_api_keys,
    load_read_key,
)
from rig.errors import ConfigError

KEY = "0123456789abcdef" * 2
READ = "fedcba9876543210" * 2
ODD = "Sl/r1g+k3y&n=m?x%7e~*!"  # characters a URL encodes or splits on


@pytest.fixture(autouse=True)
def no_keys_given(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in (KEY_ENV, READ_KEY_ENV, "CREDENTIALS_DIRECTORY"):
        monkeypatch.delenv(name, raising=False)


def _file(tmp_path: Path, data: bytes, name: str = "key") -> Path:
    path = tmp_path / name
    path.write_bytes(data)
    path.chmod(0o600)
    return path


def _refusal(key_file: Path, tmp_path: Path) -> str:
    with pytest.raises(ConfigError) as caught:
        load_api_key(key_file, tmp_path / "data")
    assert caught.value.source == "--api-key-file"
    return str(caught.value)


# -- key files --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"\xef\xbb\xbf" + KEY.encode(), "begins with a UTF-8 byte order mark"),
        (b"\xff\xfe" + KEY.encode("utf-16-le"), "begins with a UTF-16 byte order mark"),
        (KEY.encode() + "é".encode(), "holds a non-ASCII byte (0xc3) at offset 32"),
        ("ключ-ключ-ключ-ключ".encode(), "holds a non-ASCII byte (0xd0) at offset 0"),
        (KEY.encode() + b"\n" + KEY.encode(), "holds a line break at character 33"),
        (KEY.encode() + b"\r" + KEY.encode(), "holds a line break at character 33"),
        (KEY.encode() + b"\n\n", "holds a line break at character 33"),
        (KEY.encode() + b"\r\n\r\n", "holds a line break at character 33"),
        (b"0123456789 abcdef0123456789", "holds a space at character 11"),
        (b" " + KEY.encode(), "holds a space at character 1"),
        (KEY.encode() + b" \n", "holds a space at character 33"),
        (KEY.encode() + b"\t", "holds a control character (0x09) at character 33"),
        (KEY.encode() + b"\x00", "holds a control character (0x00) at character 33"),
        (KEY.encode() + b"\x7f", "holds a control character (0x7f) at character 33"),
        (b"", "the API key is empty"),
        (b"\n", "the API key is empty"),
        (b"\r\n", "the API key is empty"),
        (b"k" * (MAX_KEY_BYTES + 1), f"holds more than {MAX_KEY_BYTES} bytes"),
        (b"k" * MAX_KEY_BYTES + b"\n", f"holds more than {MAX_KEY_BYTES} bytes"),
        (b"k" * 1_000_000, f"holds more than {MAX_KEY_BYTES} bytes"),
        (b"changeme", "the API key is a placeholder"),
        (b"short\n", "the API key is shorter than 16 characters"),
    ],
)
def test_a_key_file_that_no_client_could_match_is_refused(tmp_path: Path, data: bytes, reason: str) -> None:
    path = _file(tmp_path, data)
    message = _refusal(path, tmp_path)
    assert f"--api-key-file: {path}" in message and reason in message
    assert KEY not in message  # never quoted


@pytest.mark.parametrize("ending", ["", "\n", "\r\n"])
def test_a_key_file_may_end_in_one_line_break(tmp_path: Path, ending: str) -> None:
    assert load_api_key(_file(tmp_path, (KEY + ending).encode()), tmp_path) == KEY
    assert load_api_key(_file(tmp_path, (ODD + ending).encode()), tmp_path) == ODD
    longest = "k" * MAX_KEY_BYTES
    assert load_api_key(_file(tmp_path, longest.encode()), tmp_path) == longest


def test_a_directory_is_refused(tmp_path: Path) -> None:
    (tmp_path / "keys").mkdir()
    assert "is a directory, not a regular file" in _refusal(tmp_path / "keys", tmp_path)


def test_a_device_is_refused_without_reading_it(tmp_path: Path) -> None:
    assert "/dev/zero is a character device, not a regular file" in _refusal(Path("/dev/zero"), tmp_path)
    (tmp_path / "link").symlink_to("/dev/zero")
    assert f"{tmp_path / 'link'} is a character device" in _refusal(tmp_path / "link", tmp_path)


@pytest.mark.timeout(10)
def test_a_fifo_is_refused_at_once(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "fifo")  # no writer: open() without O_NONBLOCK would wait for one for ever
    assert "is a FIFO (named pipe), not a regular file" in _refusal(tmp_path / "fifo", tmp_path)


def test_what_is_not_a_regular_file_is_not_even_opened(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Opening a device can act on it (a tape rewinds, a modem hangs up): stat() comes first."""
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "link").symlink_to("/dev/zero")
    opened: list[str] = []
    real_open = os.open

    def recorded(path: Any, *args: Any, **kwargs: Any) -> int:
        opened.append(str(path))
        return real_open(path, *args, **kwargs)

    with monkeypatch.context() as m:
        m.setattr(os, "open", recorded)
        for path in (Path("/dev/zero"), tmp_path / "link", tmp_path / "fifo", tmp_path):
            _refusal(path, tmp_path)
        assert load_api_key(_file(tmp_path, KEY.encode()), tmp_path) == KEY
    assert opened == [str(tmp_path / "key")]


@pytest.mark.timeout(10)
def test_a_fifo_swapped_in_after_the_check_is_refused_at_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The file checked by stat() is not necessarily the one opened: open() must not block and
    the opened file is checked again."""
    fifo, regular = tmp_path / "fifo", _file(tmp_path, KEY.encode())
    os.mkfifo(fifo)
    real_stat = os.stat

    def swapped(path: Any, *args: Any, **kwargs: Any) -> os.stat_result:
        return real_stat(regular if Path(path) == fifo else path, *args, **kwargs)

    with monkeypatch.context() as m:
        m.setattr(os, "stat", swapped)
        message = _refusal(fifo, tmp_path)
    assert "is a FIFO (named pipe), not a regular file" in message


def test_no_more_than_4_kib_and_a_byte_is_read(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = _file(tmp_path, b"k" * 10_000_000)
    asked: list[int] = []
    real_read = os.read

    def counted(fd: int, n: int) -> bytes:
        asked.append(n)
        return real_read(fd, n)

    with monkeypatch.context() as m:
        m.setattr(os, "read", counted)
        message = _refusal(path, tmp_path)
    assert "holds more than 4096 bytes" in message
    assert asked and sum(asked) <= MAX_KEY_BYTES + 1


def test_an_unreadable_or_missing_file_is_refused(tmp_path: Path) -> None:
    assert "cannot read" in _refusal(tmp_path / "missing", tmp_path)
    assert "No such file or directory" in _refusal(tmp_path / "missing", tmp_path)


# -- the environment, the systemd credential, the generated key -------------------------------------


@pytest.mark.parametrize(
    ("value", "reason"),
    [
        ("\n", "is empty"),
        (KEY + "\n\n", "holds a line break at character 33"),
        (KEY[:8] + "\n" + KEY, "holds a line break at character 9"),
        (KEY + " ", "holds a space at character 33"),
        ("\ufeff" + KEY, "holds a non-ASCII character (U+FEFF) at character 1"),
        (KEY + "é", "holds a non-ASCII character (U+00E9) at character 33"),
        ("k" * (MAX_KEY_BYTES + 1), f"is longer than {MAX_KEY_BYTES} characters"),
        ("changeme", "is a placeholder"),
    ],
)
def test_an_unfit_key_in_the_environment_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, value: str, reason: str
) -> None:
    monkeypatch.setenv(KEY_ENV, value)
    with pytest.raises(ConfigError, match=re.escape(f"{KEY_ENV}: the API key {reason}")):
        load_api_key(None, tmp_path)
    monkeypatch.setenv(READ_KEY_ENV, value)
    with pytest.raises(ConfigError, match=re.escape(f"{READ_KEY_ENV}: the API key {reason}")):
        load_read_key(None)


def test_the_environment_key_may_end_in_a_line_break(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for value in (KEY, KEY + "\n", KEY + "\r\n"):
        monkeypatch.setenv(KEY_ENV, value)
        assert load_api_key(None, tmp_path) == KEY
    assert not (tmp_path / GENERATED_KEY).exists()


def test_the_credential_follows_the_same_rules(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    credentials = tmp_path / "credentials"
    credentials.mkdir()
    monkeypatch.setenv("CREDENTIALS_DIRECTORY", str(credentials))
    monkeypatch.setenv(KEY_ENV, READ)  # the credential comes first
    _file(credentials, (KEY + "\n").encode(), KEY_CREDENTIAL)
    assert load_api_key(None, tmp_path) == KEY
    assert load_api_key(_file(tmp_path, ODD.encode()), tmp_path) == ODD  # the option comes before it
    _file(credentials, b"\xef\xbb\xbf" + KEY.encode(), KEY_CREDENTIAL)
    with pytest.raises(ConfigError, match=f"credential {KEY_CREDENTIAL}: .* begins with a UTF-8 byte order mark"):
        load_api_key(None, tmp_path)
    (credentials / KEY_CREDENTIAL).unlink()
    os.mkfifo(credentials / KEY_CREDENTIAL)  # present but unfit: refused, not passed over
    with pytest.raises(ConfigError, match=f"credential {KEY_CREDENTIAL}: .* is a FIFO"):
        load_api_key(None, tmp_path)
    (credentials / KEY_CREDENTIAL).unlink()
    assert load_api_key(None, tmp_path) == READ  # no credential: the environment


def test_without_a_key_one_is_generated_and_kept(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(KEY_ENV, "")  # set but empty: not given
    data = tmp_path / "data"
    key = load_api_key(None, data)
    assert len(key) == 64 and (data / GENERATED_KEY).stat().st_mode & 0o777 == 0o600
    assert load_api_key(None, data) == key
    (data / GENERATED_KEY).write_text("weak\n")
    with pytest.raises(ConfigError, match="the stored API key is too weak; delete the file"):
        load_api_key(None, data)
    (data / GENERATED_KEY).unlink()
    (data / GENERATED_KEY).symlink_to("/dev/zero")
    with pytest.raises(ConfigError, match="is a character device"):
        load_api_key(None, data)


# -- the read-only key ------------------------------------------------------------------------------


def test_the_read_key_is_optional_and_comes_from_its_own_sources(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    admin = _file(tmp_path, KEY.encode())
    assert load_api_keys(admin, None, tmp_path) == ApiKeys(KEY, None)
    assert load_read_key(None) is None
    keys = load_api_keys(admin, _file(tmp_path, (READ + "\r\n").encode(), "read"), tmp_path)
    assert (keys.admin, keys.read, keys.values()) == (KEY, READ, (KEY, READ))
    monkeypatch.setenv(READ_KEY_ENV, ODD)
    assert load_api_keys(admin, None, tmp_path).read == ODD
    credentials = tmp_path / "credentials"
    credentials.mkdir()
    monkeypatch.setenv("CREDENTIALS_DIRECTORY", str(credentials))
    _file(credentials, READ.encode(), READ_KEY_CREDENTIAL)
    assert load_api_keys(admin, None, tmp_path).read == READ  # the credential before the environment
    assert load_api_keys(None, None, tmp_path).admin != READ  # the admin key is not taken from it


def test_the_read_key_follows_the_same_rules(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    admin = _file(tmp_path, KEY.encode())
    for data, reason in [
        (b"\xef\xbb\xbf" + READ.encode(), "byte order mark"),
        (READ.encode() + b"\nx", "line break"),
        (b"", "is empty"),
        (b"k" * (MAX_KEY_BYTES + 1), "holds more than"),
        (b"short", "shorter than 16"),
    ]:
        with pytest.raises(ConfigError, match=f"--read-key-file: .*{reason}") as caught:
            load_api_keys(admin, _file(tmp_path, data, "read"), tmp_path)
        assert caught.value.source == "--read-key-file"
    with pytest.raises(ConfigError, match=r"--read-key-file: .* is a character device"):
        load_api_keys(admin, Path("/dev/zero"), tmp_path)


def test_the_read_key_must_differ_from_the_api_key(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    admin = _file(tmp_path, KEY.encode())
    with pytest.raises(ConfigError, match="--read-key-file: the read-only key is the API key itself"):
        load_api_keys(admin, _file(tmp_path, (KEY + "\n").encode(), "read"), tmp_path)
    monkeypatch.setenv(READ_KEY_ENV, KEY)
    with pytest.raises(ConfigError, match=f"{READ_KEY_ENV}: the read-only key is the API key itself"):
        load_api_keys(admin, None, tmp_path)
    generated = load_api_key(None, tmp_path / "data")
    monkeypatch.setenv(READ_KEY_ENV, generated)
    with pytest.raises(ConfigError, match="the read-only key is the API key itself"):
        load_api_keys(None, None, tmp_path / "data")


def test_keys_are_never_shown() -> None:
    keys = ApiKeys(KEY, READ)
    assert KEY not in repr(keys) and READ not in repr(keys) and KEY not in str(keys) and READ not in f"{keys}"
    assert repr(keys) == "ApiKeys(admin=<hidden>, read=<hidden>)"
    assert repr(ApiKeys(KEY)) == "ApiKeys(admin=<hidden>, read=None)"


# -- the command line -------------------------------------------------------------------------------


def _serve(tmp_path: Path, *options: str) -> subprocess.CompletedProcess[str]:
    slrig = Path(sys.executable).with_name("slrig")
    command = [str(slrig)] if slrig.exists() else [sys.executable, "-m", "rig.cli"]
    env = {k: v for k, v in os.environ.items() if k not in (KEY_ENV, READ_KEY_ENV, "CREDENTIALS_DIRECTORY")}
    return subprocess.run(
        [*command, "serve", "--port", "0", *options], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60
    )


@pytest.mark.timeout(120)
def test_slrig_serve_refuses_an_unfit_key_file_with_exit_2(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "fifo")
    admin = _file(tmp_path, KEY.encode(), "admin")
    cases = [
        (["--api-key-file", str(_file(tmp_path, b"\xef\xbb\xbf" + KEY.encode()))], "byte order mark"),
        (["--api-key-file", "/dev/zero"], "/dev/zero is a character device"),
        (["--api-key-file", str(tmp_path / "fifo")], "is a FIFO"),
        (["--api-key-file", str(admin), "--read-key-file", str(admin)], "the read-only key is the API key"),
        (["--api-key-file", str(admin), "--read-key-file", str(tmp_path / "fifo")], "--read-key-file: "),
    ]
    for options, reason in cases:
        start = time.monotonic()
        run = _serve(tmp_path, *options)
        assert run.returncode == 2, run.stderr
        assert reason in run.stderr and options[-2] + ": " in run.stderr
        assert KEY not in run.stderr
        assert time.monotonic() - start < 30
