"""A running run's lock, and its queue of pending interventions.

**The lock** (``_running.lock`` in a local run directory) is held with ``flock`` by the process that
runs the evolution (``genr8 run``/``resume``, role ``run``) and, for the moment it writes, by
``genr8 edit`` (role ``edit``). The kernel drops it when its holder dies, so a killed driver never
leaves a run looking busy. The file says who holds it (role, pid, host, since) for messages; whether
it is held is what the kernel answers, never what the file says. Its holder removes the file when it
lets go (the run finished, failed or was interrupted), so only a killed holder leaves one behind; a
process that locked a file removed meanwhile sees it is no longer the one at the path and tries again.

**The queue** (``queue/NNNNNNNNNN.json``) holds interventions asked for while the run is running (by
``genr8 edit`` or the studio). A request is written under the next free number with an exclusive link,
so two writers never overwrite each other: the loser of a race takes the next number. The coordinator,
the run's only writer, takes the requests in number order (as generations complete,
``intervene.take_queued``), records each as ``edit`` records an edit (a configuration version and
an ``intervention`` event naming the request's ``id``), then deletes the file; a request whose ``id``
is already recorded (a crash between the two) is only deleted. Requests are plain JSON data; nothing
in them is code.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import socket
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import StoreError
from genr8_dist.store._fs import RunFS

if TYPE_CHECKING:
    from genr8_dist.store.lease import Lease
    from genr8_dist.store.live import LiveView

__all__ = ["LOCK_NAME", "QUEUE_DIR", "LockAndQueue", "Queued", "RunLock", "enqueue", "lock_holder", "queued"]

LOCK_NAME = "_running.lock"
QUEUE_DIR = "queue"
_QUEUED = re.compile(r"^(\d{10})\.json$")
MAX_REQUEST_BYTES = 1 << 20


@dataclass(frozen=True, slots=True)
class Queued:
    """One pending request: its file name, its number (the order it is taken in) and its content."""

    name: str
    number: int
    request: dict[str, Any]


class RunLock:
    """The run directory's lock for ``role`` (``"run"`` or ``"edit"``); see the module docstring.

    ``acquire()`` returns False when a running run holds it (a role ``edit`` holder is waited for, up
    to ``wait`` seconds). On S3 the lock is a lease object of the same name, taken and renewed with
    conditional writes (``store/lease.py``). On other object stores there is no lock: ``acquire``
    returns True and the single-writer rule is the user's."""

    def __init__(self, rfs: RunFS, role: str, *, wait: float = 10.0) -> None:
        self._rfs = rfs
        self.role = role
        self.wait = wait
        self._fd: int | None = None
        self._lease: Lease | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None or (self._lease is not None and self._lease.held)

    def check(self) -> None:
        """Before a commit: ``StoreError`` when this holder's lease was lost (``Lease.check``)."""
        if self._lease is not None:
            self._lease.check()

    def acquire(self) -> bool:
        import fcntl

        if self._fd is not None or self._lease is not None:
            return True
        if self._rfs.local_root is None:
            return self._acquire_lease()
        path = os.path.join(self._rfs.local_root, LOCK_NAME)
        deadline = time.monotonic() + self.wait
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                holder = lock_holder(self._rfs)
                if holder is not None and holder.get("role") == "run":
                    return False
                if time.monotonic() > deadline:
                    who = f" (pid {holder.get('pid')})" if holder else ""
                    raise StoreError(f"{self._rfs.show()}: another command holds the run's lock{who}; "
                                     "try again when it has finished") from None
                time.sleep(0.05)
                continue
            try:
                current = os.stat(path).st_ino
            except FileNotFoundError:
                current = None
            if current != os.fstat(fd).st_ino:   # its holder removed it as we locked it: lock the new one
                os.close(fd)
                continue
            info = {"role": self.role, "pid": os.getpid(), "host": socket.gethostname(),
                    "since": datetime.now(UTC).isoformat()}
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(info).encode(), 0)
            self._fd = fd
            return True

    def _acquire_lease(self) -> bool:
        from genr8_dist.store.lease import Lease

        objects = self._rfs.objects()
        if objects is None:
            return True
        deadline = time.monotonic() + self.wait
        while True:
            lease = Lease(objects, LOCK_NAME, self.role)
            holder = lease.acquire()
            if holder is None:
                self._lease = lease
                return True
            if holder.get("role") == "run":
                return False
            if time.monotonic() > deadline:
                raise StoreError(f"{self._rfs.show()}: another command holds the run's lease (pid "
                                 f"{holder.get('pid')} on {holder.get('host')}); try again when it has "
                                 "finished")
            time.sleep(0.2)

    def release(self) -> None:
        if self._lease is not None:
            lease, self._lease = self._lease, None
            lease.release()
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
        if self._rfs.local_root is not None:   # removed while still held: no holder can meet a stale one
            with contextlib.suppress(OSError):
                os.unlink(os.path.join(self._rfs.local_root, LOCK_NAME))
        os.close(fd)   # closing the descriptor drops the flock

    def __enter__(self) -> RunLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def lock_holder(rfs: RunFS) -> dict[str, Any] | None:
    """Who holds the run's lock (role, pid, host, since), or None when nobody does."""
    import fcntl

    if rfs.local_root is None:
        from genr8_dist.store.lease import lease_holder

        objects = rfs.objects()
        return None if objects is None else lease_holder(objects, LOCK_NAME)
    path = os.path.join(rfs.local_root, LOCK_NAME)
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            data = os.pread(fd, 4096, 0)
            try:
                info = json.loads(data.decode() or "{}")
            except (UnicodeDecodeError, json.JSONDecodeError):
                info = {}
            return info if isinstance(info, dict) else {}
        return None
    finally:
        os.close(fd)


def queued(rfs: RunFS) -> list[Queued]:
    """The pending requests, in the order they are taken (a torn or foreign file is skipped)."""
    out = []
    for name in rfs.listdir(QUEUE_DIR):
        match = _QUEUED.match(name)
        if not match:
            continue
        try:
            request = json.loads(rfs.read_bytes(f"{QUEUE_DIR}/{name}").decode())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            continue
        if isinstance(request, dict) and isinstance(request.get("id"), str):
            out.append(Queued(name, int(match.group(1)), request))
    return sorted(out, key=lambda q: q.number)


def enqueue(rfs: RunFS, request: dict[str, Any]) -> Queued:
    """Add ``request`` (JSON data; an ``id`` is given to it) at the end of the queue."""
    body = dict(request, id=request.get("id") or secrets.token_hex(8),
                queued=datetime.now(UTC).isoformat())
    data = json.dumps(body, sort_keys=True).encode()
    if len(data) > MAX_REQUEST_BYTES:
        raise StoreError(f"an intervention of {len(data)} bytes is too large to queue "
                         f"(at most {MAX_REQUEST_BYTES})")
    rfs.makedirs(QUEUE_DIR)
    for _ in range(1000):
        numbers = [int(m.group(1)) for m in map(_QUEUED.match, rfs.listdir(QUEUE_DIR)) if m]
        number = max(numbers, default=0) + 1
        name = f"{number:010d}.json"
        try:
            rfs.write_exclusive(f"{QUEUE_DIR}/{name}", data)
        except FileExistsError:
            continue   # another writer took this number: take the next one
        return Queued(name, number, body)
    raise StoreError(f"{rfs.show(QUEUE_DIR)}: could not add a request (1000 tries lost to other writers)")


def dequeue(rfs: RunFS, item: Queued) -> None:
    """Remove a request once it is recorded in the run store (or refused)."""
    rfs.delete(f"{QUEUE_DIR}/{item.name}")


class LockAndQueue:
    """A store's lock and queue (mixed into ``RunStore``, which sets the attributes)."""

    _fs: RunFS
    writer_lock: RunLock | None   # checked before each manifest (a lease on S3)

    def lock(self, role: str, *, wait: float = 10.0) -> RunLock:
        """The run's lock for ``role`` (``"run"``: the evolution's driver; ``"edit"``: one edit); this
        store's commits check it first (on S3, that its lease is still theirs)."""
        self.writer_lock = RunLock(self._fs, role, wait=wait)
        return self.writer_lock

    def running(self) -> dict[str, Any] | None:
        """Who runs the run now (role, pid, host, since), or None when no process holds its lock."""
        return lock_holder(self._fs)

    def enqueue(self, request: dict[str, Any]) -> Queued:
        """Queue an intervention for the running run's next epoch (plain JSON data)."""
        return enqueue(self._fs, request)

    def live(self) -> LiveView:
        """The live view of the running run (``store/live.py``): what it has completed, not committed."""
        from genr8_dist.store import live

        return live.LiveView(self._fs)

    def queued(self) -> list[Queued]:
        """The pending interventions, in the order the coordinator takes them."""
        return queued(self._fs)

    def dequeue(self, item: Queued) -> None:
        """Remove a pending intervention that has been recorded (only the run's writer does this)."""
        dequeue(self._fs, item)
