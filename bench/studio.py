"""Studio scale figures (issue 13): a synthetic run of 16 islands x 200 individuals x 1,000
generations, written through the store's own writer, opened in the studio over HTTP; then one more
epoch committed and the time until the studio's answers show it.

    python bench/studio.py                        # writes the run to a temporary folder (~2 min)
    python bench/studio.py --run /tmp/synth       # reuses (or first writes) the run there

Printed: the seconds to open (state and the newest generation: what the page shows first; then the
curves of the whole run),
the seconds from a commit until state and curves include it (the page polls once a second, so a
designer sees a commit within that plus this), and the size of the curves' JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
import urllib.request

from genr8_dist.store import RunStore, write_synthetic_run
from genr8_dist.store.synthetic import _text_pool, synthetic_epoch
from genr8_dist.studio import Studio

ISLANDS, POP, GENERATIONS, SEED = 16, 200, 1000, 1


def _get(port: int, path: str) -> bytes:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=120) as r:
        return r.read()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", default=None, help="where the synthetic run is (written if missing)")
    args = parser.parse_args()
    run = args.run or os.path.join(tempfile.mkdtemp(prefix="genr8-studio-bench-"), "run")
    if not os.path.isdir(os.path.join(run, "_manifest")):
        t = time.perf_counter()
        write_synthetic_run(run, ISLANDS, GENERATIONS, POP, SEED)
        print(f"wrote {ISLANDS} x {POP} x {GENERATIONS} = {ISLANDS * POP * GENERATIONS:,} individuals "
              f"in {time.perf_counter() - t:.1f} s")
    store = RunStore.open(run)
    studio = Studio(run, port=0).start()
    try:
        t = time.perf_counter()
        state = json.loads(_get(studio.port, "/api/state"))
        generation = json.loads(_get(studio.port, "/api/generation"))
        first = generation["individuals"][0]["id"]
        painted = time.perf_counter() - t
        curves = _get(studio.port, "/api/curves")
        opened = time.perf_counter() - t
        print(f"open: state + generation {generation['generation']} ({len(generation['individuals'])} "
              f"individuals, best {first}) in {painted:.2f} s; with the curves of the whole run "
              f"{opened:.2f} s (curves JSON {len(curves) / 1e6:.2f} MB for "
              f"{len(json.loads(curves)['generation'])} generations; the first read of a run checks every "
              "file's sha256)")

        first = max(store.refresh().committed_generations().values()) + 1
        table = synthetic_epoch(store, SEED, GENERATIONS // 10, first, first + 9, ISLANDS, POP, (16, 128),
                                _text_pool(SEED))
        t = time.perf_counter()
        store.commit_table(table)
        committed = time.perf_counter() - t
        t = time.perf_counter()
        state = json.loads(_get(studio.port, "/api/state"))
        curves = json.loads(_get(studio.port, "/api/curves"))
        update = time.perf_counter() - t
        assert state["generation"] == first + 9 and curves["generation"][-1] == first + 9, "update not seen"
        print(f"live update: a commit of {table.num_rows:,} rows ({committed:.2f} s to write) shown by "
              f"state + curves in {update:.2f} s after it (the page polls every 1 s)")
    finally:
        studio.close()
    print(f"load average at the end: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
