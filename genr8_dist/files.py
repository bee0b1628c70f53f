"""Writing the files users ask for (meshes, pictures, tables, reports) as every Unix tool does.

Every atomic write in the package goes through this module: a temporary name beside the target
(``temp_beside``), then one rename onto it (``replace_atomically``). The run store adds durability
(``store._fs``: the bytes and the folder fsynced, and filesystems other than local); ``replacing`` is
the writer for everything written beside it. What a path names decides how it is written:

- ``-`` is standard output;
- a device, a FIFO or a socket (``/dev/stdout``, ``/dev/null``, a named pipe) is written through, in
  one stream, never replaced;
- a symlink is followed: its target is written (and replaced atomically in the target's folder), the
  link stays a link;
- a regular file (or a new name) is written to a temporary file beside it, then renamed onto it, so a
  reader never sees half a file and a failure leaves it as it was. A new file gets the mode the umask
  gives (0644 under umask 022), a replaced one keeps its mode.

Whatever the target, the bytes are first written whole to a temporary file, so a failure midway
writes nothing to a stream either.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import stat
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = [
    "STDOUT",
    "TMP_PREFIX",
    "is_stdout",
    "is_stream",
    "replace_atomically",
    "replacing",
    "sync_folder",
    "temp_beside",
]

STDOUT = "-"
TMP_PREFIX = ".tmp-"   # every temporary file's name starts so (the run store's collector knows them)


def temp_beside(path: str | os.PathLike[str]) -> str:
    """A new temporary name in ``path``'s folder, ``.tmp-<name>-<pid>-<8 hex digits>``: no other writer
    uses it, and the pid tells whether its writer is still alive (``store/garbage.py``)."""
    folder, name = os.path.split(os.fspath(path))
    return os.path.join(folder, f"{TMP_PREFIX}{name}-{os.getpid()}-{secrets.token_hex(4)}")


def replace_atomically(tmp: str | os.PathLike[str], target: str | os.PathLike[str], *,
                       durable: bool = False) -> None:
    """Rename ``tmp`` (a file or a symlink) onto ``target`` in one step: readers see the old one or the
    new. If the rename fails ``tmp`` is removed. ``durable``: the folder is fsynced after, so that the
    rename outlives a crash."""
    try:
        os.replace(tmp, target)
    except OSError:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    if durable:
        sync_folder(os.path.dirname(os.fspath(target)) or ".")


def sync_folder(folder: str | os.PathLike[str]) -> None:
    """fsync ``folder`` where the system allows it (a rename or link inside it is then on disk)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def is_stdout(path: str | os.PathLike[str]) -> bool:
    """Whether writing ``path`` writes this process's standard output (``-``, ``/dev/stdout``, or
    any name of the file, pipe or terminal it is): its messages then belong on standard error."""
    if os.fspath(path) == STDOUT:
        return True
    try:
        return os.path.samestat(os.stat(path), os.fstat(1))
    except (OSError, ValueError):
        return False


def is_stream(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is ``-`` or names a device, FIFO or socket: written through, never replaced."""
    if os.fspath(path) == STDOUT:
        return True
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not stat.S_ISREG(mode) and not stat.S_ISDIR(mode)


def _umask() -> int:
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextmanager
def replacing(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path to write to; when the block succeeds its bytes become ``path`` as the module
    docstring says (standard output, written through a device or FIFO, or renamed onto the file or
    the symlink's target), and when it fails it is removed and ``path`` is as it was. The folder of a
    file must exist (``FileNotFoundError`` otherwise)."""
    if is_stdout(path) or is_stream(path):
        with _streaming(path) as tmp:
            yield tmp
        return
    target = Path(os.path.realpath(path)) if os.path.islink(path) else Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except FileNotFoundError:
        mode = 0o666 & ~_umask()
    tmp = Path(temp_beside(folder / target.name))
    tmp.open("xb").close()
    try:
        yield tmp
        os.chmod(tmp, mode)
        replace_atomically(tmp, target)
    finally:
        if tmp.exists():
            tmp.unlink()


@contextmanager
def _streaming(path: str | os.PathLike[str]) -> Iterator[Path]:
    folder = tempfile.mkdtemp(prefix="genr8-out-")
    tmp = Path(folder) / "out"
    try:
        yield tmp
        with open(tmp, "rb") as source:
            if is_stdout(path):   # through our own descriptor: a shell's `>>` appends, a pipe streams
                sys.stdout.flush()
                sink = getattr(sys.stdout, "buffer", None)
                if sink is None:
                    sys.stdout.write(source.read().decode("utf-8", "replace"))
                else:
                    shutil.copyfileobj(source, sink)
                    sink.flush()
            else:
                with open(path, "wb") as sink_file:
                    shutil.copyfileobj(source, sink_file)
    finally:
        with contextlib.suppress(OSError):
            shutil.rmtree(folder)
