"""Start-up: ``genr8 run`` imports the coordinator and the store while Ray starts, not before."""

from __future__ import annotations

import subprocess
import sys

import pytest


def test_the_run_command_starts_ray_before_importing_the_coordinator():
    """Everything up to ``ray.init`` is light: the heavy modules come in a thread meanwhile."""
    code = ("import sys; import genr8_dist.cli.run, genr8_dist.distributed.session, genr8_dist.distributed; "
            "heavy = [m for m in ('genr8_dist.distributed.coordinator', 'genr8_dist.store', 'pyarrow', "
            "'genr8_dist.evolution') if m in sys.modules]; print(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_meanwhile_runs_beside_the_caller_and_keeps_its_errors_to_itself():
    from genr8_dist.distributed.session import _meanwhile

    seen = []
    thread = _meanwhile(lambda: seen.append("done"))
    assert thread is not None
    thread.join()
    assert seen == ["done"]

    def fails():
        raise ImportError("no such module")

    failing = _meanwhile(fails)
    assert failing is not None
    failing.join()   # no exception escapes; the main thread meets it again where it needs the module
    assert _meanwhile(None) is None


def test_a_sigterm_swallowed_inside_ray_start_up_still_stops_without_a_traceback(monkeypatch, capsys):
    """Ray's SIGTERM handler raises SystemExit; landing in a fork callback it is only printed as
    "Exception ignored". connect_ray keeps it and stops as for any SIGTERM while Ray starts."""
    import gc

    import ray

    from genr8_dist.distributed import reaper, session

    class ExitsWhenCollected:
        def __del__(self) -> None:
            raise SystemExit(15)

    def init(*args: object, **kwargs: object) -> None:
        ExitsWhenCollected()   # collected at once: an unraisable SystemExit, as in a fork callback
        gc.collect()

    shutdowns: list[bool] = []
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", init)
    monkeypatch.setattr(ray, "shutdown", lambda: shutdowns.append(True))
    monkeypatch.setattr(reaper, "start_reaper", lambda: None)
    with pytest.raises(KeyboardInterrupt, match="SIGTERM while Ray was starting"), session.connect_ray():
        pass
    assert shutdowns == [True]
    assert "Exception ignored" not in capsys.readouterr().err


# --- a Ray that does not start: one line, exit 2, nothing locked or written -------------------------

_INJECT = """\
import sys
import ray._private.node
from genr8_dist.distributed import session

def timed_out(self, *args, **kwargs):
    raise Exception("The current node timed out during startup. This could happen because some of the "
                    "raylet failed to startup or the GCS has become overloaded.")

ray._private.node.Node.__init__ = timed_out
session.RETRY_PAUSE = 0.0
from genr8_dist.cli import main
sys.exit(main(sys.argv[1:]))
"""

_CONFIG = """\
universe = "default"
seed = 3

[genome]
length = 30
max_depth = 4

[ea]
population = 4
generations = 1
tournament = 2

[environment]
steps = 2

[islands]
count = 1
"""


def _genr8_with_ray_timing_out(tmp_path, *args: str) -> subprocess.CompletedProcess[str]:
    script = tmp_path / "inject.py"
    script.write_text(_INJECT)
    env = {k: v for k, v in __import__("os").environ.items() if k != "RAY_ADDRESS"}
    return subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True,
                          timeout=120, env=env)


@pytest.fixture(scope="module")
def resumable_run(tmp_path_factory, ray_local):
    """A run whose last generation is still to come (made with the tests' Ray, then lengthened)."""
    from genr8_dist.cli import main

    root = tmp_path_factory.mktemp("startup")
    (root / "run.toml").write_text(_CONFIG)
    run_dir = root / "run"
    assert main(["run", str(root / "run.toml"), "--run-dir", str(run_dir), "--quiet"]) == 0
    assert main(["edit", str(run_dir), "--generations", "1"]) == 0
    return run_dir


@pytest.mark.slow
def test_a_local_ray_that_times_out_is_one_line_and_leaves_the_run_unlocked(resumable_run, tmp_path, capsys):
    from genr8_dist.cli import main
    from genr8_dist.store import RunStore

    done = _genr8_with_ray_timing_out(tmp_path, "resume", str(resumable_run), "--quiet")
    assert done.returncode == 2, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("genr8: error: a new local Ray did not start (2 tries;")
    assert "timed out during startup" in lines[0] and "--cpus" in lines[0]
    store = RunStore.open(resumable_run)
    assert store.running() is None
    assert store.committed_generations() == {0: 1}
    capsys.readouterr()
    (resumable_run / "configs" / "notes.txt").write_text("a user's file")
    assert main(["resume", str(resumable_run), "--quiet"]) == 0   # not refused "running already"
    assert RunStore.open(resumable_run).committed_generations() == {0: 2}
    out = capsys.readouterr().out
    assert f"{resumable_run}: set aside 1 file(s) the run did not write (configs/notes.txt) in " in out
    assert (resumable_run / "_foreign" / "configs" / "notes.txt").read_text() == "a user's file"


@pytest.mark.slow
def test_a_new_run_whose_ray_times_out_writes_nothing(tmp_path):
    (tmp_path / "run.toml").write_text(_CONFIG)
    done = _genr8_with_ray_timing_out(tmp_path, "run", str(tmp_path / "run.toml"), "--run-dir",
                                      str(tmp_path / "run"), "--quiet")
    assert done.returncode == 2
    assert len(done.stderr.splitlines()) == 1 and "did not start" in done.stderr
    assert not (tmp_path / "run").exists()


@pytest.mark.slow
def test_a_cluster_address_whose_ray_init_fails_is_one_line_and_unlocked(resumable_run, tmp_path):
    """Something answers at the address (the probe passes) but Ray's connection fails."""
    import socket

    from genr8_dist.cli import main
    from genr8_dist.store import RunStore

    assert main(["edit", str(resumable_run), "--generations", "1"]) == 0   # something left to run
    before = RunStore.open(resumable_run).committed_generations()
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen()
        port = listener.getsockname()[1]
        done = _genr8_with_ray_timing_out(tmp_path, "resume", str(resumable_run), "--quiet", "--address",
                                          f"127.0.0.1:{port}")
    assert done.returncode == 2
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"genr8: error: cannot connect to Ray at 127.0.0.1:{port}")
    assert "ray status --address" in lines[0]
    store = RunStore.open(resumable_run)
    assert store.running() is None and store.committed_generations() == before


def test_a_start_that_fails_once_is_tried_again_with_patient_waits(monkeypatch):
    import os

    import ray

    from genr8_dist.distributed import reaper, session

    seen: list[str | None] = []
    wait = "RAY_gcs_server_port_wait_time_s"

    def init(**kwargs: object) -> None:
        seen.append(os.environ.get(wait))
        if len(seen) == 1:
            raise Exception("The current node timed out during startup.")

    monkeypatch.delenv(wait, raising=False)
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", init)
    monkeypatch.setattr(ray, "shutdown", lambda: None)
    monkeypatch.setattr(reaper, "start_reaper", lambda: None)
    monkeypatch.setattr(session, "RETRY_PAUSE", 0.0)
    with session.connect_ray():
        pass
    assert seen == ["120", "120"]   # two tries, each with Ray's GCS wait raised from its 30 s
    assert wait not in os.environ   # put back once Ray is up

    monkeypatch.setattr(ray, "init", lambda **kwargs: (_ for _ in ()).throw(Exception("boom\nmore")))
    refused = r"^a new local Ray did not start \(2 tries; Ray said: boom\)"
    with pytest.raises(session.RunError, match=refused), session.connect_ray():
        pass
