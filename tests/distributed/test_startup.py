"""Start-up: ``genr8 run`` imports the coordinator and the store while Ray starts, not before."""

from __future__ import annotations

import subprocess
import sys


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

    import pytest
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
