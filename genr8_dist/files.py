"""Writing the files users ask for (meshes, pictures, tables, reports) so that they appear whole.

The run store has its own durable writer (``store._fs``: fsync, filesystems other than local); this
is the one for everything written beside it.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["replacing"]


@contextmanager
def replacing(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed onto ``path`` when the block succeeds and
    removed when it fails, so a reader never sees half a file and a failure leaves ``path`` as it was.
    The folder must exist (``FileNotFoundError`` otherwise)."""
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.replace(tmp, target)
    finally:
        if tmp.exists():
            tmp.unlink()
