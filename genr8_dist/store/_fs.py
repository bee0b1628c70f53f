"""File access for a run directory on a local disk or any pyarrow filesystem.

On a local disk (``LocalFileSystem``, or a ``SubTreeFileSystem`` over one) a file is written to a
temporary name in the same folder, fsynced, then renamed into place, and the folder is fsynced (the
name and the rename are ``genr8_dist.files``'s, as every atomic write in the package): a
crash leaves the old file or the new one, never half of one. Manifests are *linked* into place, which
fails if the name exists, so two writers cannot both commit the same version. On other filesystems
(object stores) a write is one PUT, which is atomic there; readers never trust a file the manifest
does not name, and a torn manifest fails its checksum and is skipped. On S3 an exclusive write (a
manifest, a queued request) is a conditional PUT, ``If-None-Match: *`` (``store/_s3.py``), so there too
two writers cannot both create the same name; on other object stores it is a check, then a PUT.
"""

from __future__ import annotations

import contextlib
import os
import posixpath
from typing import TYPE_CHECKING

from genr8_dist.errors import StoreError
from genr8_dist.files import TMP_PREFIX as TMP_PREFIX
from genr8_dist.files import replace_atomically, sync_folder, temp_beside

if TYPE_CHECKING:
    import pyarrow.fs as pafs

    from genr8_dist.store._s3 import ObjectStore

__all__ = ["RunFS", "resolve"]


def resolve(path_or_uri: str | os.PathLike[str], filesystem: pafs.FileSystem | None = None) -> RunFS:
    """The filesystem and root of a run given as a local path, a URI (``file://``, ``s3://``...), or a
    path inside ``filesystem``."""
    import pyarrow.fs as pafs

    text = os.fspath(path_or_uri)
    if not text:
        raise StoreError("a run directory path is empty")
    if filesystem is not None:
        return RunFS(filesystem, text.rstrip("/") or "/", text)
    if "://" in text:
        try:
            fs, root = pafs.FileSystem.from_uri(text)
        except (ValueError, OSError) as exc:
            raise StoreError(f"{text}: cannot open this URI: {exc}") from None
        return RunFS(fs, root.rstrip("/") or "/", text)
    return RunFS(pafs.LocalFileSystem(), os.path.abspath(text), text)


class RunFS:
    """A run's root on a filesystem; every path given to its methods is relative to the root."""

    def __init__(self, fs: pafs.FileSystem, root: str, display: str) -> None:
        import pyarrow.fs as pafs

        self.fs = fs
        self.root = root
        self.display = display
        self.local_root: str | None = None
        self._objects: ObjectStore | bool | None = False   # False: not looked up yet
        if isinstance(fs, pafs.LocalFileSystem):
            self.local_root = root
        elif isinstance(fs, pafs.SubTreeFileSystem) and isinstance(fs.base_fs, pafs.LocalFileSystem):
            self.local_root = os.path.join(fs.base_path, root.lstrip("/"))

    # --- names -------------------------------------------------------------------------------
    def full(self, rel: str) -> str:
        """The path of ``rel`` inside the filesystem (what pyarrow readers take)."""
        return posixpath.join(self.root, rel) if rel else self.root

    def show(self, rel: str = "") -> str:
        """``rel`` as a user would name it in a message (a URI's query, its endpoint say, left out)."""
        if not rel:
            return self.display
        base = self.display.split("?", 1)[0] if "://" in self.display else self.display
        return f"{base.rstrip('/')}/{rel}"

    def objects(self) -> ObjectStore | None:
        """The conditional-write client when the run is on S3 (``store/_s3.py``), else None; a
        one-line ``StoreError`` when it is on S3 and boto3 is missing."""
        if self._objects is False:
            if self.local_root is not None:
                self._objects = None
            else:
                from genr8_dist.store._s3 import object_store

                self._objects = object_store(self.fs, self.root, self.show().split("?", 1)[0])
        assert self._objects is not True
        return self._objects

    def _local(self, rel: str) -> str:
        assert self.local_root is not None
        return os.path.join(self.local_root, *rel.split("/")) if rel else self.local_root

    # --- queries -----------------------------------------------------------------------------
    def kind(self, rel: str = "") -> str:
        """``"file"``, ``"dir"`` or ``"missing"``."""
        import pyarrow.fs as pafs

        info = self.fs.get_file_info(self.full(rel))
        if info.type == pafs.FileType.File:
            return "file"
        if info.type == pafs.FileType.Directory:
            return "dir"
        return "missing"

    def size(self, rel: str) -> int | None:
        import pyarrow.fs as pafs

        info = self.fs.get_file_info(self.full(rel))
        return info.size if info.type == pafs.FileType.File else None

    def listdir(self, rel: str = "") -> list[str]:
        """Names directly inside ``rel`` (empty when it does not exist)."""
        import pyarrow.fs as pafs

        if self.kind(rel) != "dir":
            return []
        infos = self.fs.get_file_info(pafs.FileSelector(self.full(rel), allow_not_found=True))
        return sorted(posixpath.basename(i.path.rstrip("/")) for i in infos)

    def read_bytes(self, rel: str) -> bytes:
        if self.local_root is not None:
            with open(self._local(rel), "rb") as fh:
                return fh.read()
        with self.fs.open_input_stream(self.full(rel)) as fh:
            return bytes(fh.read())

    # --- writes ------------------------------------------------------------------------------
    def makedirs(self, rel: str = "") -> None:
        if self.local_root is not None:
            os.makedirs(self._local(rel), exist_ok=True)
        else:
            self.fs.create_dir(self.full(rel), recursive=True)

    def write_atomic(self, rel: str, data: bytes | memoryview, *, durable: bool = True) -> None:
        """Put ``data`` at ``rel``, replacing what is there; readers see the old bytes or the new.
        ``durable=False``: neither the file nor its folder is fsynced (a view that a crash may lose,
        like the live view: two fsyncs were most of its cost)."""
        if self.local_root is None:
            with self.fs.open_output_stream(self.full(rel)) as fh:
                fh.write(data)
            return
        replace_atomically(self._write_temp(rel, data, durable=durable), self._local(rel), durable=durable)

    def write_new(self, rel: str, data: bytes | memoryview) -> None:
        """Put ``data`` at ``rel``, a name no other writer uses (it holds a writer token); like
        ``write_exclusive``, it never replaces a file: ``FileExistsError`` if ``rel`` exists. On an
        object store it is pyarrow's own PUT (the token makes the name this writer's)."""
        if self.local_root is None:
            self._put_checked(rel, data)
            return
        self._put_exclusive(rel, data)

    def write_exclusive(self, rel: str, data: bytes | memoryview) -> None:
        """Put ``data`` at ``rel``, which must not exist; ``FileExistsError`` if it does (the manifest
        link: whoever links manifest N first has committed N)."""
        self._put_exclusive(rel, data)

    def mtime(self, rel: str) -> float | None:
        """Seconds since the epoch of ``rel``'s last change, or None when unknown or missing."""
        import pyarrow.fs as pafs

        info = self.fs.get_file_info(self.full(rel))
        if info.type != pafs.FileType.File or info.mtime is None:
            return None
        return float(info.mtime.timestamp())

    def _put_exclusive(self, rel: str, data: bytes | memoryview) -> None:
        if self.local_root is None and (objects := self.objects()) is not None:
            from genr8_dist.store._s3 import Conflict

            try:
                objects.create(rel, data)
            except Conflict:
                raise FileExistsError(self.show(rel)) from None
            return
        if self.local_root is None:
            self._put_checked(rel, data)
            return
        tmp = self._write_temp(rel, data)
        final = self._local(rel)
        try:
            os.link(tmp, final)
        except FileExistsError:
            raise
        except OSError:  # a filesystem without hard links: check, then rename (racy, but atomic)
            if os.path.exists(final):
                raise FileExistsError(final) from None
            os.replace(tmp, final)
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
        self._sync_dir(rel)

    def _put_checked(self, rel: str, data: bytes | memoryview) -> None:
        if self.kind(rel) != "missing":
            raise FileExistsError(self.show(rel))
        with self.fs.open_output_stream(self.full(rel)) as fh:
            fh.write(data)

    def delete(self, rel: str) -> None:
        with contextlib.suppress(FileNotFoundError):
            if self.local_root is not None:
                os.unlink(self._local(rel))
            else:
                self.fs.delete_file(self.full(rel))

    def _write_temp(self, rel: str, data: bytes | memoryview, durable: bool = True) -> str:
        tmp = temp_beside(self._local(rel))
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror, self._local(rel)) from None
        done = False
        try:
            view = memoryview(data)
            while view:
                written = os.write(fd, view)
                view = view[written:]
            if durable:
                os.fsync(fd)
            done = True
        except OSError as exc:  # a full disk, say: name the file being written
            raise OSError(exc.errno, exc.strerror, self._local(rel)) from None
        finally:
            os.close(fd)
            if not done:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
        return tmp

    def _sync_dir(self, rel: str) -> None:
        sync_folder(self._local(posixpath.dirname(rel)))
