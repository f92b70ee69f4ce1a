"""The daemon's API keys: where they come from and what a key may be.

The admin key (every request the API guards) comes from --api-key-file, the systemd credential
`slrig-api-key` or $SLRIG_API_KEY, in that order; with none of them, from <data_dir>/api-key,
generated there (mode 0600) on first start. The optional read-only key (for dashboards and
automation that only watch) comes from --read-key-file, the credential `slrig-read-key` or
$SLRIG_READ_KEY; without any of them there is none.

A key is printable ASCII without spaces (0x21..0x7e), at most MAX_KEY_BYTES long, and strong
(rig.api.security.check_key_strength). A key file may end in one line break ("\\n" or "\\r\\n"),
must be a regular file (not a directory, device, FIFO or socket: those could hang the start or
grow memory without bound) and must not begin with a byte order mark. Anything else is refused
at start with a ConfigError naming the source and the reason (the CLI exits with code 2), rather
than accepted and then matching no client's key. Error messages never quote a key.
"""

from __future__ import annotations

import logging
import os
import secrets
import stat
from dataclasses import dataclass
from pathlib import Path

from rig.api import check_key_strength
from rig.errors import ConfigError

log = logging.getLogger(__name__)

KEY_ENV = "SLRIG_API_KEY"
KEY_CREDENTIAL = "slrig-api-key"  # systemd LoadCredential= name
GENERATED_KEY = "api-key"
READ_KEY_ENV = "SLRIG_READ_KEY"
READ_KEY_CREDENTIAL = "slrig-read-key"
MAX_KEY_BYTES = 4096  # a key file holds at most this many bytes (line break included)
BOMS = (  # longest first: the UTF-32 LE mark begins with the UTF-16 LE one
    (b"\xff\xfe\x00\x00", "UTF-32"),
    (b"\x00\x00\xfe\xff", "UTF-32"),
    (b"\xef\xbb\xbf", "UTF-8"),
    (b"\xff\xfe", "UTF-16"),
    (b"\xfe\xff", "UTF-16"),
)
FILE_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
)


@dataclass(frozen=True, repr=False)
class ApiKeys:
    """The daemon's keys: `admin` for everything the API guards, `read` (or None) for reads only.
    Neither is ever shown by repr() or str()."""

    admin: str
    read: str | None = None

    def __repr__(self) -> str:
        return f"ApiKeys(admin=<hidden>, read={'<hidden>' if self.read is not None else None})"

    def values(self) -> tuple[str, ...]:
        """The keys that are set, the admin key first (what the log redaction hides)."""
        return (self.admin,) if self.read is None else (self.admin, self.read)


def load_api_keys(key_file: Path | None, read_key_file: Path | None, data_dir: Path) -> ApiKeys:
    """Both keys, each from its first source (see the module's docstring).

    Raises ConfigError when a key is unfit (see check_key), a key file cannot be read or is not a
    regular file (see read_key_file), the generated key cannot be made, or the read-only key is
    the admin key.
    """
    admin = load_api_key(key_file, data_dir)
    found = _given_key(read_key_file, "--read-key-file", READ_KEY_CREDENTIAL, READ_KEY_ENV)
    if found is None:
        return ApiKeys(admin)
    source, read = found
    if read == admin:
        raise ConfigError(source, [f"{source}: the read-only key is the API key itself; give it a key of its own"])
    return ApiKeys(admin, read)


def load_api_key(key_file: Path | None, data_dir: Path) -> str:
    """From --api-key-file, the systemd credential or $SLRIG_API_KEY, in that order; with none of
    them, the key in <data_dir>/api-key, generated there (mode 0600) on first start.

    Raises ConfigError when the key is unfit or its file cannot be read or made.
    """
    found = _given_key(key_file, "--api-key-file", KEY_CREDENTIAL, KEY_ENV)
    return found[1] if found is not None else _generated_key(data_dir / GENERATED_KEY)


def load_read_key(read_key_file: Path | None) -> str | None:
    """From --read-key-file, the systemd credential `slrig-read-key` or $SLRIG_READ_KEY, in that
    order; None without any of them. (load_api_keys also checks that it differs from the admin key.)

    Raises ConfigError when the key is unfit or its file cannot be read.
    """
    found = _given_key(read_key_file, "--read-key-file", READ_KEY_CREDENTIAL, READ_KEY_ENV)
    return found[1] if found is not None else None


def _given_key(key_file: Path | None, option: str, credential: str, env: str) -> tuple[str, str] | None:
    """(source, key) from the option's file, the credential or the environment; None without them.

    Raises ConfigError when the key found is unfit or its file cannot be read.
    """
    credentials = os.environ.get("CREDENTIALS_DIRECTORY")
    if key_file is not None:
        return option, read_key_file(key_file, option)
    if credentials and os.path.lexists(Path(credentials) / credential):  # present in any form: then it must be fit
        source = f"credential {credential}"
        return source, read_key_file(Path(credentials) / credential, source)
    if os.environ.get(env):  # set but empty: not given (as systemd's `Environment=NAME=` leaves it)
        return env, check_key(os.environ[env], env)
    return None


def check_key(key: str, source: str) -> str:
    """`key` without the one line break ("\\n" or "\\r\\n") it may end in, when it is a fit API key.

    Raises ConfigError naming `source` when it is empty, longer than MAX_KEY_BYTES, holds anything
    but printable ASCII without spaces (a line break inside, a non-ASCII or control character, a
    space) or is too weak (check_key_strength).
    """
    key = _without_line_break(key)
    problem = _form_problem(key) or check_key_strength(key)
    if problem:
        raise ConfigError(source, [f"{source}: the API key {problem}"])
    return key


def read_key_file(path: Path, source: str) -> str:
    """The key in the regular file `path` (without its one final line break), read without blocking
    and never more than MAX_KEY_BYTES + 1 bytes of it; warns when users other than its owner can
    read it.

    Raises ConfigError naming `source` and `path` when the file cannot be read, is not a regular
    file (checked before and after opening it), is empty, holds more than MAX_KEY_BYTES bytes,
    begins with a byte order mark, or holds an unfit key (see check_key).
    """
    key = _file_key(path, source)
    problem = check_key_strength(key)
    if problem:
        raise ConfigError(source, [f"{source}: {path}: the API key {problem}"])
    return key


def _file_key(path: Path, source: str) -> str:
    """The key in the file, well formed but not yet checked for strength.

    Raises ConfigError as read_key_file does, but for a weak key.
    """
    data, mode = _read_regular(path, source)
    if mode & 0o077:  # others (or the group) can read the key
        log.warning("%s: %s can be read by users other than its owner; chmod 600 it", source, path)
    if len(data) > MAX_KEY_BYTES:
        raise ConfigError(source, [f"{source}: {path} holds more than {MAX_KEY_BYTES} bytes; an API key is shorter"])
    for mark, encoding in BOMS:
        if data.startswith(mark):
            raise ConfigError(
                source, [f"{source}: {path} begins with a {encoding} byte order mark; save the key as plain ASCII"]
            )
    try:
        key = _without_line_break(data.decode("ascii"))
    except UnicodeDecodeError as exc:
        raise ConfigError(
            source,
            [
                f"{source}: {path} holds a non-ASCII byte (0x{data[exc.start]:02x}) at offset {exc.start}; "
                "an API key is printable ASCII without spaces"
            ],
        ) from None
    problem = _form_problem(key)
    if problem:
        raise ConfigError(source, [f"{source}: {path}: the API key {problem}"])
    return key


def _without_line_break(key: str) -> str:
    """`key` without one final "\\n" or "\\r\\n" (as editors and `echo` end a file)."""
    return key[:-2] if key.endswith("\r\n") else key[:-1] if key.endswith("\n") else key


def _form_problem(key: str) -> str | None:
    """Why `key` is not a well-formed key (empty, too long, not printable ASCII), or None."""
    if not key:
        return "is empty"
    if len(key) > MAX_KEY_BYTES:
        return f"is longer than {MAX_KEY_BYTES} characters"
    for position, char in enumerate(key, 1):
        if not "\x21" <= char <= "\x7e":
            return f"holds {_describe(char)} at character {position}; an API key is printable ASCII without spaces"
    return None


def _describe(char: str) -> str:
    if char in "\r\n":
        return "a line break"
    if char == " ":
        return "a space"
    if ord(char) > 0x7F:
        return f"a non-ASCII character (U+{ord(char):04X})"
    return f"a control character (0x{ord(char):02x})"


def _read_regular(path: Path, source: str) -> tuple[bytes, int]:
    """The first MAX_KEY_BYTES + 1 bytes of the regular file `path`, and its mode.

    Raises ConfigError when it cannot be read or is not a regular file.
    """
    try:
        before = os.stat(path)  # before opening: a FIFO would block open(), a device never end read()
        _require_regular(before.st_mode, path, source)
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC)
        try:
            after = os.fstat(fd)  # what was opened: the path may have been replaced since stat()
            _require_regular(after.st_mode, path, source)
            chunks: list[bytes] = []
            size = 0
            while size <= MAX_KEY_BYTES:
                chunk = os.read(fd, MAX_KEY_BYTES + 1 - size)
                if not chunk:
                    break
                chunks.append(chunk)
                size += len(chunk)
        finally:
            os.close(fd)
    except OSError as exc:
        raise ConfigError(source, [f"{source}: cannot read {path}: {exc.strerror}"]) from None
    return b"".join(chunks), after.st_mode


def _require_regular(mode: int, path: Path, source: str) -> None:
    """Raises ConfigError when `mode` is not a regular file's."""
    if stat.S_ISREG(mode):
        return
    what = next((name for test, name in FILE_KINDS if test(mode)), "not a regular file")
    raise ConfigError(source, [f"{source}: {path} is {what}, not a regular file holding the key"])


def _generated_key(path: Path) -> str:
    """The key in `path`, generated there (mode 0600) when there is no such file.

    Raises ConfigError when it cannot be made or read, or the stored key is unfit.
    """
    source = str(path)
    if not os.path.lexists(path):
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o600)
        except FileExistsError:
            pass  # another start made it just now: read it
        except OSError as exc:
            raise ConfigError(source, [f"{source}: cannot create the API key file: {exc.strerror}"]) from None
        else:
            try:
                with os.fdopen(fd, "w") as f:
                    f.write(secrets.token_hex(32) + "\n")
                    f.flush()
                    os.fsync(f.fileno())
            except OSError as exc:  # a full disk: no half-written key left for the next start
                path.unlink(missing_ok=True)
                raise ConfigError(source, [f"{source}: cannot write the API key file: {exc.strerror}"]) from None
            log.info("generated an API key in %s (mode 0600); clients send it as X-API-Key", path)
    key = _file_key(path, source)
    if check_key_strength(key):
        raise ConfigError(source, [f"{path}: the stored API key is too weak; delete the file to generate one"])
    return key
