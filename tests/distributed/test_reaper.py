"""A driver killed with SIGKILL leaves no Ray process behind 10 s later (distributed/reaper.py)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from genr8_dist.distributed.reaper import _alive, _descendants, _table

DRIVER = textwrap.dedent("""
    import time
    from genr8_dist.distributed.session import connect_ray
    with connect_ray(None, 1) as ray:
        ray.get(ray.remote(lambda: 1).remote())  # a worker too
        print("up", flush=True)
        time.sleep(120)
""")


def _tree_of(pid: int) -> dict[int, int]:
    table = _table()
    return {p: table[p][1] for p in _descendants({pid}, table)}


@pytest.mark.slow
@pytest.mark.parametrize("kill_after", [1.5, "up"])
def test_no_ray_process_outlives_a_sigkilled_driver_by_10_s(kill_after) -> None:
    driver = subprocess.Popen([sys.executable, "-c", DRIVER], stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": os.getcwd()})
    seen: dict[int, int] = {}
    deadline = time.monotonic() + (90 if kill_after == "up" else kill_after)
    if kill_after == "up":
        assert driver.stdout is not None
        assert driver.stdout.readline() == "up\n"
    while time.monotonic() < deadline and kill_after != "up":
        seen.update(_tree_of(driver.pid))
        time.sleep(0.05)
    seen.update(_tree_of(driver.pid))
    driver.send_signal(signal.SIGKILL)
    driver.wait()
    seen = {p: s for p, s in seen.items() if _table().get(p, (0, s))[1] == s}
    time.sleep(10)
    left = [p for p, s in seen.items() if _alive(p, s)]
    names = []
    for p in left:
        try:
            with open(f"/proc/{p}/cmdline", "rb") as fh:
                names.append(fh.read().replace(b"\0", b" ").decode()[:80])
        except OSError:
            pass
    for p in left:  # do not leave them to the next test
        os.kill(p, signal.SIGKILL)
    if kill_after == "up":
        assert len(seen) >= 3  # the GCS, the raylet, a worker...: there was something to end
    assert names == []
