"""Writing the files users ask for (meshes, pictures, tables, reports) as every Unix tool does.

The run store has its own durable writer (``store._fs``: fsync, filesystems other than local); this
is the one for everything written beside it. What a path names decides how it is written:

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
import shutil
import stat
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["STDOUT", "is_stdout", "is_stream", "replacing"]

STDOUT = "-"


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
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, mode)
        os.replace(tmp, target)
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
