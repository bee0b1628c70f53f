"""Studio scale figures (issue 13): a synthetic run of 16 islands x 200 individuals x 1,000
generations, written through the store's own writer, opened in the studio over HTTP; then one more
epoch committed and the time until the studio's answers show it.

    python bench/studio.py                        # writes the run to a temporary folder (~2 min)
    python bench/studio.py --run /tmp/synth       # reuses (or first writes) the run there
    python bench/studio.py --run /tmp/synth --profile   # and cProfile's view of the first paint

Printed:
- open: from launching ``genr8 studio RUN`` (a new process: interpreter, imports, the store opened)
  until the studio has answered the state and the newest generation, what the page paints first;
  then until it has answered the curves of the whole run (every file read and checked: sha256);
- the same first paint asked of a studio already serving in this process (no warm-up: a cold store);
- live: from a commit of one more epoch until state, the newest generation and the curves show it
  (the page polls once a second, so a designer sees a commit within that plus this);
- the load average at each step (the machine is shared).
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

from genr8_dist.store import RunStore, write_synthetic_run
from genr8_dist.store.synthetic import _text_pool, synthetic_epoch
from genr8_dist.studio import Studio

ISLANDS, POP, GENERATIONS, SEED = 16, 200, 1000, 1


def _get(port: int, path: str) -> bytes:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=300) as r:
        return r.read()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _load() -> str:
    return f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs"


def _from_launch(run: str) -> None:
    """First paint and curves of a ``genr8 studio`` started now, timed from its launch."""
    port = _free_port()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    t = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "genr8_dist.cli", "studio", run, "--port", str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    try:
        while True:
            try:
                state = json.loads(_get(port, "/api/state"))
                break
            except (urllib.error.URLError, ConnectionError):
                if proc.poll() is not None:
                    raise SystemExit(f"genr8 studio exited: {proc.stderr.read().decode()}") from None
                time.sleep(0.02)
        generation = json.loads(_get(port, "/api/generation"))
        painted = time.perf_counter() - t
        curves = json.loads(_get(port, "/api/curves"))
        opened = time.perf_counter() - t
        print(f"open from launch: state (generation {state['generation']}) + generation "
              f"{generation['generation']} ({len(generation['individuals'])} individuals) "
              f"in {painted:.2f} s; "
              f"curves of {len(curves['generation'])} generations at {opened:.2f} s ({_load()})")
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", default=None, help="where the synthetic run is (written if missing)")
    parser.add_argument("--profile", action="store_true", help="print cProfile's view of the first paint")
    args = parser.parse_args()
    run = args.run or os.path.join(tempfile.mkdtemp(prefix="genr8-studio-bench-"), "run")
    if not os.path.isdir(os.path.join(run, "_manifest")):
        t = time.perf_counter()
        write_synthetic_run(run, ISLANDS, GENERATIONS, POP, SEED)
        print(f"wrote {ISLANDS} x {POP} x {GENERATIONS} = {ISLANDS * POP * GENERATIONS:,} individuals "
              f"in {time.perf_counter() - t:.1f} s")
    store = RunStore.open(run)
    size = sum(os.path.getsize(f) for f in store.individual_files())
    print(f"run: {sum(e['rows'] for e in store.manifest['individuals']):,} individuals in "
          f"{len(store.individual_files())} files, {size / 1e6:.0f} MB")

    _from_launch(run)

    studio = Studio(run, port=0)   # not started: no warm-up, so the first paint reads a cold store
    import threading

    threading.Thread(target=studio.httpd.serve_forever, daemon=True).start()
    try:
        profile = None
        if args.profile:
            import cProfile

            profile = cProfile.Profile()
            studio.view = _Profiled(studio.view, profile)
        t = time.perf_counter()
        json.loads(_get(studio.port, "/api/state"))
        generation = json.loads(_get(studio.port, "/api/generation"))
        painted = time.perf_counter() - t
        if profile is not None:
            import pstats

            pstats.Stats(profile).sort_stats("cumulative").print_stats(25)
            studio.view = studio.view.view
        curves = _get(studio.port, "/api/curves")
        opened = time.perf_counter() - t
        print(f"open in a serving studio: state + generation {generation['generation']} in {painted:.2f} s; "
              f"curves at {opened:.2f} s (JSON {len(curves) / 1e6:.2f} MB) ({_load()})")

        first = max(store.refresh().committed_generations().values()) + 1
        table = synthetic_epoch(store, SEED, GENERATIONS // 10, first, first + 9, ISLANDS, POP, (16, 128),
                                _text_pool(SEED))
        t = time.perf_counter()
        store.commit_table(table)
        committed = time.perf_counter() - t
        t = time.perf_counter()
        state = json.loads(_get(studio.port, "/api/state"))
        generation = json.loads(_get(studio.port, "/api/generation"))
        curves = json.loads(_get(studio.port, "/api/curves"))
        update = time.perf_counter() - t
        assert state["generation"] == first + 9 and generation["generation"] == first + 9 \
            and curves["generation"][-1] == first + 9, "update not seen"
        print(f"live update: a commit of {table.num_rows:,} rows ({committed:.2f} s to write) shown by "
              f"state + newest generation + curves {update:.2f} s after it; the page polls every 1 s, so "
              f"a designer sees it within {1 + update:.2f} s ({_load()})")
    finally:
        studio.close()


class _Profiled:
    """The studio's ``RunView`` with its state and generation answers profiled."""

    def __init__(self, view: object, profile: object) -> None:
        self.view, self.profile = view, profile

    def __getattr__(self, name: str) -> object:
        found = getattr(self.view, name)
        if name not in ("state", "generation"):
            return found

        def profiled(*args: object, **kwargs: object) -> object:
            return self.profile.runcall(found, *args, **kwargs)
        return profiled


if __name__ == "__main__":
    main()
