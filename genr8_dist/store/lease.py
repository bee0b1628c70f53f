"""The run's lease on an object store: one writer at a time across machines.

On a local disk the run's lock is an ``flock`` (``store/pending.py``), which the kernel drops when its
holder dies. An object store has no locks, so a run there is held by a *lease*: the object
``_running.lock`` beside the manifests, a small JSON body (role, pid, host, since, a random token, the
lease's length in seconds) written only with conditional PUTs (``store/_s3.py``):

- **taking it**: if there is no lease object, create it with ``If-None-Match: *``; if there is one
  that is free (released by its holder, or *expired*: not renewed for longer than its own length, by
  the server's clock), replace it with ``If-Match`` on the ETag just read. Of any number of drivers
  racing, exactly one PUT succeeds; the others read the winner's lease and are refused.
- **keeping it**: the holder renews it (``If-Match`` on its own last ETag) every quarter of its
  length, from a background thread, and again before any commit when the last renewal is older than
  half the length. A renewal that fails its condition means another driver took the lease over (this
  one stalled past the expiry): the holder knows it lost, and refuses every later commit.
- **giving it back**: on release the holder marks the object released (``If-Match`` again), so the
  next driver takes it at once. A driver that was killed leaves an unreleased lease: on the same
  machine (same host name and boot) whose process is gone it is free at once; elsewhere it is free
  when it expires (``GENR8_LEASE_SECONDS``, default 60 s).

The lease keeps a second driver from starting; the manifests keep a stalled one from committing:
each manifest is created with ``If-None-Match: *`` (``RunFS.write_exclusive``), so whoever creates
number N+1 first has committed and the other is refused before it changes anything.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import socket
import threading
import time
from datetime import UTC, datetime
from typing import Any

from genr8_dist.errors import StoreError
from genr8_dist.store._s3 import Conflict, ObjectStore

__all__ = ["DEFAULT_SECONDS", "Lease", "lease_holder", "lease_seconds"]

DEFAULT_SECONDS = 60.0


def lease_seconds() -> float:
    """The length of a new lease: ``GENR8_LEASE_SECONDS`` (at least 1) or ``DEFAULT_SECONDS``."""
    text = os.environ.get("GENR8_LEASE_SECONDS", "").strip()
    if not text:
        return DEFAULT_SECONDS
    try:
        value = float(text)
    except ValueError:
        raise StoreError(f"GENR8_LEASE_SECONDS={text!r}: expected a number of seconds") from None
    if not value >= 1.0:
        raise StoreError(f"GENR8_LEASE_SECONDS={text!r}: a lease lasts at least 1 second")
    return value


def _boot_id() -> str:
    try:
        with open("/proc/sys/kernel/random/boot_id", encoding="ascii") as fh:
            return fh.read().strip()
    except OSError:
        return ""


def _decode(data: bytes) -> dict[str, Any] | None:
    try:
        body = json.loads(data.decode())
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None
    return body if isinstance(body, dict) else None


def _gone_here(body: dict[str, Any]) -> bool:
    """Whether the lease's holder was a process of this machine, since its last boot, that has ended."""
    if body.get("host") != socket.gethostname() or not body.get("boot") or body.get("boot") != _boot_id():
        return False
    pid = body.get("pid")
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (OSError, OverflowError):
        return False
    return False


def _free(body: dict[str, Any] | None, age: float) -> bool:
    if body is None:   # not a lease this code wrote: a torn or foreign body holds nothing
        return True
    if body.get("released"):
        return True
    try:
        length = float(body.get("seconds", DEFAULT_SECONDS))
    except (TypeError, ValueError):
        length = DEFAULT_SECONDS
    return age > length or _gone_here(body)


def lease_holder(store: ObjectStore, rel: str) -> dict[str, Any] | None:
    """Who holds the lease (role, pid, host, since...), or None when it is free."""
    found = store.get(rel)
    if found is None:
        return None
    body = _decode(found.data)
    return None if _free(body, found.age) else body


class Lease:
    """One holder's lease at ``rel`` of ``store`` for ``role``; see the module docstring."""

    def __init__(self, store: ObjectStore, rel: str, role: str, *, seconds: float | None = None) -> None:
        self._store = store
        self._rel = rel
        self.role = role
        self.seconds = float(seconds if seconds is not None else lease_seconds())
        self._etag: str | None = None
        self._renewed = 0.0          # time.monotonic() when the last successful PUT was sent
        self._lost: str | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._body: dict[str, Any] = {}

    @property
    def held(self) -> bool:
        return self._etag is not None and self._lost is None

    def _encode(self, **extra: Any) -> bytes:
        return json.dumps(dict(self._body, **extra), sort_keys=True).encode()

    def acquire(self) -> dict[str, Any] | None:
        """Take the lease: None when taken, else the body of the lease that holds it."""
        self._body = {"role": self.role, "pid": os.getpid(), "host": socket.gethostname(), "boot": _boot_id(),
                      "since": datetime.now(UTC).isoformat(), "token": secrets.token_hex(8),
                      "seconds": self.seconds, "renewals": 0}
        for _ in range(20):
            found = self._store.get(self._rel)
            sent = time.monotonic()
            try:
                if found is None:
                    etag = self._store.create(self._rel, self._encode())
                else:
                    body = _decode(found.data)
                    if not _free(body, found.age):
                        assert body is not None
                        return body
                    etag = self._store.replace(self._rel, self._encode(), found.etag)
            except Conflict:
                continue   # another driver wrote it between our read and our PUT: read again
            with self._lock:
                self._etag, self._renewed, self._lost = etag, sent, None
            self._start_renewing()
            return None
        raise StoreError(f"{self._store.display}: could not take the run's lease (20 tries lost to "
                         "other writers)")

    def _start_renewing(self) -> None:
        self._stop.clear()
        self._thread = threading.Thread(target=self._renew_loop, name="genr8-lease", daemon=True)
        self._thread.start()

    def _renew_loop(self) -> None:
        while not self._stop.wait(self.seconds / 4) and self._lost is None:
            # a network failure is retried at the next tick; the lease lapses by time alone
            with contextlib.suppress(OSError, StoreError):
                self.renew()

    def renew(self) -> None:
        """Extend the lease (``If-Match`` on its last ETag); ``StoreError`` once it is lost."""
        with self._lock:
            if self._lost is not None:
                raise StoreError(self._lost)
            if self._etag is None:
                return
            self._body["renewals"] = int(self._body.get("renewals", 0)) + 1
            sent = time.monotonic()
            try:
                self._etag = self._store.replace(self._rel, self._encode(), self._etag)
            except Conflict:
                self._lost = (f"{self._store.display}: this driver's lease on the run was taken over by "
                              "another driver (it had not been renewed for longer than "
                              f"{self.seconds:g} s); only one writer may commit")
                raise StoreError(self._lost) from None
            self._renewed = sent

    def check(self) -> None:
        """Before a commit: the lease is still this holder's (renewed now if its last renewal is older
        than half its length); ``StoreError`` when it is lost or cannot be confirmed in time."""
        with self._lock:
            lost, etag, age = self._lost, self._etag, time.monotonic() - self._renewed
        if lost is not None:
            raise StoreError(lost)
        if etag is None:
            raise StoreError(f"{self._store.display}: this driver does not hold the run's lease")
        if age > self.seconds / 2:
            self.renew()
            with self._lock:
                if time.monotonic() - self._renewed >= self.seconds:
                    raise StoreError(f"{self._store.display}: the run's lease could not be renewed in "
                                     "time; only one writer may commit")

    def release(self) -> None:
        """Give the lease back (marked released, so the next driver takes it at once)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5)
        with self._lock:
            etag, self._etag = self._etag, None
            if etag is None or self._lost is not None:
                return
            with contextlib.suppress(Conflict, OSError):   # taken over meanwhile, or unreachable: it expires
                self._store.replace(self._rel, self._encode(released=True), etag)
