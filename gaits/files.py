"""Files: writing one so that it is either the old one or the whole new one, and reading a
user's file only when it is a regular file of a sane size (ours).

A disk that fills, a quota, or an interrupt in the middle of a write must not leave a half
parameter file where a good one was: the text goes to a temporary file beside the target, is
flushed to the disk (``fsync``), and only then renamed over it (``os.replace`` is atomic on POSIX
and Windows within one file system). If anything fails on the way the temporary file is removed
and the target is untouched; the ``OSError`` goes on to the caller, naming the target.
"""

from __future__ import annotations

import errno
import os
import stat
import tempfile
from pathlib import Path


def write_text_atomic(path: str | Path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path``: all of it or, on any error, nothing (the old file stays)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = text.encode(encoding)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        if path.exists():
            try:
                os.chmod(tmp, path.stat().st_mode & 0o7777)
            except OSError:
                pass
        else:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError) and exc.filename is None:
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
        raise
    return path


#: Largest file of each kind the tool reads (ours: a hundred times the largest real one we know),
#: so that ``/dev/zero`` or a mistaken log file is refused at once instead of filling memory.
MAX_BYTES = {"yaml": 1_000_000, "csv": 10_000_000, "mjcf": 50_000_000, "urdf": 50_000_000, "mesh": 100_000_000}


def read_bytes_checked(path: str | Path, what: str, limit: int, error: type[Exception]) -> bytes:
    """The bytes of a user's file, or one ``error`` naming the file and what it is instead.

    Checked before anything is read, without blocking: a missing file, a directory, a symlink
    loop, a FIFO, a socket or a device (a FIFO is never opened, so nothing waits for a writer),
    and a file larger than ``limit`` bytes. The file is opened non-blocking and checked again on
    its descriptor, and at most ``limit`` + 1 bytes are read, so a file swapped or grown in
    between is caught too. ``what`` names the kind of file in messages.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        if os.path.islink(path):
            raise error(f"{path}: a symbolic link to a missing file, expected a {what} file") from None
        raise error(f"{path}: no such {what} file") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise error(f"{path}: a loop of symbolic links, expected a {what} file") from None
        raise error(f"{path}: cannot read the {what} file ({exc.strerror})") from None
    _check_kind(path, st, what, limit, error)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise error(f"{path}: cannot read the {what} file ({exc.strerror})") from None
    try:
        _check_kind(path, os.fstat(fd), what, limit, error)
        chunks, total = [], 0
        while total <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
    except OSError as exc:
        raise error(f"{path}: cannot read the {what} file ({exc.strerror})") from None
    finally:
        os.close(fd)
    if total > limit:
        raise error(f"{path}: larger than a {what} file's limit of {limit:,} bytes")
    return b"".join(chunks)


def _check_kind(path: Path, st: os.stat_result, what: str, limit: int, error: type[Exception]) -> None:
    mode = st.st_mode
    if stat.S_ISDIR(mode):
        raise error(f"{path}: is a directory, expected a {what} file")
    if not stat.S_ISREG(mode):
        kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
                else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file")
        raise error(f"{path}: is {kind}, expected a regular {what} file")
    if st.st_size > limit:
        raise error(f"{path}: {st.st_size:,} bytes, larger than a {what} file's limit of {limit:,} bytes")
