"""Ray's processes end with the command that started them, even when it is killed with SIGKILL.

A local Ray (``genr8 run`` / ``resume`` without ``--address``) is a tree of processes under the driver:
the GCS, the raylet, its agents (``ray::DashboardAgent``, ``ray::RuntimeEnvAgent``) and workers.
``ray.shutdown()`` ends them when the command ends normally or is interrupted, but a SIGKILL leaves
them running for a minute or more. So the driver starts a reaper first: a small process in a session
of its own that notes the driver's descendants every ``POLL_SECONDS`` and, when the driver is gone,
sends each of them (and anything they started since) SIGTERM, then SIGKILL after ``GRACE_SECONDS``.
A process is known by its pid and start time, so a recycled pid is never hit. Linux only (it reads
``/proc``); elsewhere ``start_reaper`` does nothing.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time

__all__ = ["GRACE_SECONDS", "POLL_SECONDS", "start_reaper"]

POLL_SECONDS = 0.25
GRACE_SECONDS = 2.0


def _stat(pid: int) -> tuple[int, int, int] | None:
    """``(parent pid, start time, process group)`` of ``pid``, or None when it is gone (or a zombie)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            text = fh.read().decode("ascii", "replace")
    except OSError:
        return None
    fields = text[text.rfind(")") + 2:].split()
    if not fields or fields[0] in ("Z", "X"):
        return None
    return int(fields[1]), int(fields[19]), int(fields[2])


def _table() -> dict[int, tuple[int, int, int]]:
    out = {}
    for name in os.listdir("/proc"):
        if name.isdigit() and (st := _stat(int(name))) is not None:
            out[int(name)] = st
    return out


def _descendants(roots: set[int], table: dict[int, tuple[int, int, int]]) -> set[int]:
    found, frontier = set(), set(roots)
    while frontier:
        nxt = {pid for pid, (ppid, _, _) in table.items() if ppid in frontier and pid not in found}
        found |= nxt
        frontier = nxt
    return found


def _alive(pid: int, started: int) -> bool:
    st = _stat(pid)
    return st is not None and st[1] == started


def reap(driver: int, started: int) -> None:
    """Watch ``driver`` (pid, start time); when it is gone, end every process it left behind."""
    me = os.getpid()
    known: dict[int, int] = {}
    own = _stat(driver)
    group = own[2] if own is not None else -1
    while _alive(driver, started):
        table = _table()
        for pid in _descendants({driver}, table) - {me}:
            known.setdefault(pid, table[pid][1])
        time.sleep(POLL_SECONDS)
    table = _table()
    left = {pid: st for pid, st in known.items() if _alive(pid, st)}
    for pid, (ppid, st, pgrp) in table.items():  # started in the driver's last moments, now orphaned
        if ppid == 1 and pgrp == group and st >= started and pid != me:
            left.setdefault(pid, st)
    for pid in _descendants(set(left), table) - {me}:  # what they started since the last look
        left.setdefault(pid, table[pid][1])
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for pid, st in left.items():
            if _alive(pid, st):
                with contextlib.suppress(OSError):
                    os.kill(pid, sig)
        deadline = time.monotonic() + GRACE_SECONDS
        while time.monotonic() < deadline and any(_alive(p, s) for p, s in left.items()):
            time.sleep(0.05)


_STARTED: list[subprocess.Popen[bytes]] = []


def start_reaper() -> subprocess.Popen[bytes] | None:
    """Start the reaper for this process once (see the module docstring); None where /proc is missing."""
    st = _stat(os.getpid())
    if st is None:
        return None
    if _STARTED and _STARTED[0].poll() is None:
        return _STARTED[0]
    _STARTED[:] = [subprocess.Popen(
        [sys.executable, "-m", "genr8_dist.distributed.reaper", str(os.getpid()), str(st[1])],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True, close_fds=True)]
    return _STARTED[0]


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a Ctrl-C at the terminal is the driver's to handle
    reap(int(sys.argv[1]), int(sys.argv[2]))
