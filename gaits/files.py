"""Files: writing one so that it is either the old one or the whole new one, and reading a
user's file only when it is a regular file of a sane size (ours).

A disk that fills, a quota, or an interrupt in the middle of a write must not leave a half
parameter file where a good one was: the text goes to a temporary file beside the target, is
flushed to the disk (``fsync``), and only then renamed over it (``os.replace`` is atomic on POSIX
and Windows within one file system). If anything fails on the way the temporary file is removed
and the target is untouched; the ``OSError`` goes on to the caller, naming the target.

Several files that belong together (a parameter set and its joint or servo table) are written as
one (:func:`write_files_atomic`): each new text to a temporary file beside its target, flushed;
then a manifest naming every (temporary, target) pair, written atomically: that write is the
commit; then the renames, then the manifest is removed. A kill before the commit leaves every old
file (and temporaries, removed by the next writer or reader once their process is gone); a kill
after it leaves a manifest that the next writer or reader of that folder
(:func:`complete_pending_writes`, called by ``load_gait_file`` and by every group write) carries
out first, so each reader sees all the new files or all the old ones, never a mix.
"""

from __future__ import annotations

import errno
import json
import os
import stat
import tempfile
from pathlib import Path
from typing import Mapping


#: an OSError of a path that cannot name the file asked for (the user's mistake, not the disk's), in
#: words: the command line's and the robot loop's one-line errors
PATH_PROBLEMS = {errno.ENOTDIR: "a part of the path is a file, not a folder",
                 errno.ENAMETOOLONG: "a name in the path is longer than the file system allows",
                 errno.EISDIR: "it is a folder, not a file", errno.ELOOP: "too many symbolic links",
                 errno.EEXIST: "a file stands where a folder is needed"}


class FolderRefused(FileNotFoundError):
    """A folder that cannot be made where it was asked (ours): ``mkdir`` with its parents says
    ENOENT only when the file system there takes no new folder (``/proc``, ``/sys``), the user's
    path, not a bug; the command line and the robot loop say it in one line."""


#: the words for :class:`FolderRefused`
FOLDER_REFUSED = "no folder can be made there (the file system there takes none)"


def make_folder(path: str | Path) -> Path:
    """``path`` as a folder, made with its parents if missing; a :class:`FolderRefused` naming it
    where the file system will not hold one."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileNotFoundError as exc:
        raise FolderRefused(errno.ENOENT, FOLDER_REFUSED, exc.filename or str(path)) from None
    return path


def probe_folder(path: str | Path) -> Path:
    """Check, before long work, that ``path`` can be a folder to write in: it is one, or it and its
    missing parents can be made (they are made and removed again: nothing is left). The errors are
    :func:`make_folder`'s (and an existing file's ``FileExistsError``), naming the path."""
    path = Path(path)
    missing = []
    p = path
    while not os.path.lexists(p) and p != p.parent:
        missing.append(p)
        p = p.parent
    make_folder(path)
    for made in missing:                     # the deepest first
        try:
            made.rmdir()
        except OSError:                      # another process wrote there meanwhile: leave it
            break
    return path


def write_text_atomic(path: str | Path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path``: all of it or, on any error, nothing (the old file stays)."""
    return write_bytes_atomic(path, text.encode(encoding))


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path``: all of it or, on any error, nothing (the old file stays)."""
    path = Path(path)
    make_folder(path.parent)
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


_MANIFEST = ".gait-tuner-group."        # + pid.random.json: a committed group write's renames
_GROUP_TMP = ".group-tmp"                # suffix of a group write's temporary files: .NAME.PID.RANDOM.group-tmp


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def complete_pending_writes(directory: str | Path) -> int:
    """Carry out every committed group write left in ``directory`` by a process that was killed
    (its manifest's renames, then the manifest removed), and remove the temporaries of group
    writes that never committed and whose process is gone. Returns the groups completed."""
    directory = Path(directory)
    try:
        names = os.listdir(directory)
    except OSError:
        return 0
    done = 0
    for name in sorted(n for n in names if n.startswith(_MANIFEST) and n.endswith(".json")):
        path = directory / name
        try:
            pairs = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue                       # being written (not committed yet) or already gone
        for tmp, final in pairs:
            try:
                os.replace(directory / tmp, directory / final)
            except FileNotFoundError:
                pass                       # renamed already (by its writer, or another reader)
        _fsync_dir(directory)
        try:
            os.unlink(path)
            done += 1
        except FileNotFoundError:
            pass
    referenced = set()
    for name in os.listdir(directory):
        if name.startswith(_MANIFEST) and name.endswith(".json"):
            try:
                referenced |= {tmp for tmp, _ in json.loads((directory / name).read_text(encoding="utf-8"))}
            except (OSError, ValueError):
                pass
    for name in names:
        if name.startswith(_MANIFEST) and name.endswith(".staged"):      # a manifest never committed
            parts = name.split(".")
            if len(parts) >= 3 and parts[2].isdigit() and not _alive(int(parts[2])):
                try:
                    os.unlink(directory / name)
                except OSError:
                    pass
        if name.endswith(_GROUP_TMP) and name not in referenced:
            parts = name.split(".")
            pid = int(parts[-3]) if len(parts) >= 4 and parts[-3].isdigit() else None
            if pid is not None and not _alive(pid):
                try:
                    os.unlink(directory / name)
                except OSError:
                    pass
    return done


def write_files_atomic(files: Mapping[str | Path, str], encoding: str = "utf-8") -> list[Path]:
    """Write several texts, each to its path, as one (the module docstring): after a kill at any
    moment every reader that goes through :func:`complete_pending_writes` sees all of them new or
    all old. The paths must share one folder. On an error nothing is changed and the ``OSError``
    names the file."""
    paths = [Path(p) for p in files]
    folders = {p.parent.resolve() for p in paths}
    if len(folders) != 1:
        raise ValueError(f"write_files_atomic: the files must share one folder, got {sorted(map(str, folders))}")
    directory = make_folder(paths[0].parent)
    complete_pending_writes(directory)
    umask = os.umask(0)
    os.umask(umask)
    temps: list[Path] = []
    manifest: Path | None = None
    try:
        for path, text in zip(paths, files.values()):
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=_GROUP_TMP, dir=directory)
            temps.append(Path(tmp))
            with os.fdopen(fd, "wb") as fh:
                fh.write(text.encode(encoding))
                fh.flush()
                os.fsync(fh.fileno())
            mode = path.stat().st_mode & 0o7777 if path.exists() else 0o666 & ~umask
            os.chmod(tmp, mode)
        pairs = [[t.name, p.name] for t, p in zip(temps, paths)]
        fd, staged = tempfile.mkstemp(prefix=f"{_MANIFEST}{os.getpid()}.", suffix=".staged", dir=directory)
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(pairs, fh)
            fh.flush()
            os.fsync(fh.fileno())
        manifest = Path(staged).with_suffix(".json")
        os.replace(staged, manifest)                # the commit
        _fsync_dir(directory)
    except BaseException as exc:
        for t in temps:
            try:
                os.unlink(t)
            except OSError:
                pass
        try:
            os.unlink(staged)                       # type: ignore[possibly-undefined]
        except (OSError, NameError):
            pass
        if isinstance(exc, OSError) and exc.filename is None:
            raise OSError(exc.errno, exc.strerror or str(exc), str(paths[0])) from exc
        raise
    for t, p in zip(temps, paths):
        os.replace(t, p)
    _fsync_dir(directory)
    os.unlink(manifest)
    return paths


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
