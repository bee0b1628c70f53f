"""A cluster simulator: what the engine itself costs per island, per row and per epoch as a run grows.

    python bench/scale.py --islands 256 --population 50 --cpus 64 --nodes 4 --generations 20 \\
        --interval 5 --json out.json
    python bench/scale.py --islands 4 --population 50 --cpus 16 --generations 10
    python bench/scale.py --islands 64 --population 20 --cpus 32 --nodes 4 --generations 5 --scale 0.5
    python bench/scale.py --real examples/quick.toml --islands 4 --population 50 --generations 8 \
        --sweep 1,2,4,8,16            # real evaluation, on a machine with that many cores

A run of the ``waits`` universe (bench/plugins/waits): developing an individual waits a time drawn from
the measured per-individual evaluation time distribution of the default universe (heavy tail included,
a function of the text, so deterministic) instead of computing. Waiting costs no CPU, so hundreds of
islands on tens of simulated hosts run on a 2-core machine: Ray gets ``--cpus`` logical CPUs over
``--nodes`` nodes (``ray.cluster_utils.Cluster``, several raylets on this machine), and what is left
to measure is the engine's own cost: breeding, traffic, commits, scheduling, the barrier.

It prints, and with ``--json`` writes one JSON object with: ``islands``, ``cpus``, ``nodes``, ``rows``
(committed in the run), ``epochs`` (commits), ``wall_s`` (the coordinator's run, from its creation to its
last commit; Ray's and the hosts' start-up are ``startup_s``), ``ideal_s`` (the seconds waited by every
evaluation the run stored, divided by the CPUs), ``efficiency`` (ideal / wall), ``coordinator_share``
(the driver's time outside waiting for hosts, / wall; ``coordinator_cpu_share``: the driver's CPU
seconds / wall), ``commit_p50_s``, ``commit_p99_s`` (the driver's commit of an epoch: a thread of
its own while the next epoch runs), ``commit_max_s``, ``compactions`` and ``compaction_max_s``
(the compactions that thread made after an epoch's commit, once small files held a merged file's rows),
``driver_bytes_per_row`` (bytes of the objects the driver received from hosts, pickled, per row),
``driver_peak_rss_mb`` (the driver process's peak resident memory), ``rows_per_epoch``, and the
machine's load average before and after (the machine may be shared: the waits are wall time, so
another process's load shows as lost efficiency). ``critical_s`` is the longest chain of waits no
scheduling can shorten: an island's generations follow one another, and each lasts at least its
longest evaluation, so the wall time is at least the largest sum over an island's generations of
their longest waits; ``efficiency_bound`` is the efficiency a run can reach with it (ideal over the
larger of ideal and critical). ``driver_cpu_s`` and ``driver_cpu_per_epoch_s``: the driver's CPU
seconds (the bench's own instruments left out), which a loaded machine distorts less than wall time.
``hosts_cpu_s`` (and per row, ``hosts_cpu_per_row_ms``): the CPU seconds of every island host, start-up
included: on a machine with fewer cores than hosts, hosts' CPU competes with the waits (2 cores give
at most ``2 * wall_s`` CPU seconds to everything). ``efficiency_machine_bound`` says what that allows:
ideal over the larger of ideal and the engine's CPU seconds (hosts' and driver's) divided by the
machine's ``machine_cores``; hosts' start-up is in it, so it is a little low. ``--trace-memory`` adds
``driver_traced_mb_by_commit``: the Python memory the driver holds after each commit (tracemalloc),
which stays flat when the driver keeps no history of the run. ``--timeline`` logs every wait and
adds where the CPUs' time went (``timeline_figures``): ``waited_s``, ``overshoot_ms_mean`` and
``overshoot_ms_p99``, ``waits_span_s``, ``idle_share`` and ``tail_s``.

The bench's own instruments (pickling what the driver receives to count its bytes) are left out of the
driver's time.

``--real CONFIG`` evolves a run configuration whose universe really grows and scores (its islands,
population, generations and migration interval replaced where the options give them): no waits, so
it measures real scaling and needs as many cores as ``--cpus``. ``ideal_s`` is then the evaluation
seconds of the stored individuals (as measured where they ran) over the CPUs, and ``critical_s`` is
built from those seconds. ``--sweep 1,2,4,8,16`` runs the same configuration at each of those CPU
counts in turn (a fresh Ray each time) and ends with a table: wall time, ``speedup`` over the first
count and ``scaling_efficiency`` (speedup over the CPUs' ratio: what the added CPUs gave), with the
figures above; ``--json`` then writes ``{"sweep": [...]}``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import cProfile  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import pickle  # noqa: E402
import pstats  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

ROOT = Path(__file__).resolve().parent
PLUGINS = ROOT / "plugins"


def _percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    if not ordered:
        return 0.0
    k = min(len(ordered) - 1, max(0, round(q * (len(ordered) - 1))))
    return ordered[k]


WAITS_DEFAULTS = {"islands": 16, "population": 50, "generations": 10, "interval": 5, "seed": 1}


def config_toml(args: argparse.Namespace) -> str:
    """The run configuration of the run: ``--real``'s with the options' changes, else the waits'."""
    if args.real:
        from genr8_dist.config import load_config

        config = load_config(args.real)
        islands = {"count": args.islands, "migration_interval": args.interval}
        ea = {"population": args.population, "generations": args.generations}
        return config.replace(seed=config.seed if args.seed is None else args.seed,
                              islands={k: v for k, v in islands.items() if v is not None},
                              ea={k: v for k, v in ea.items() if v is not None}).to_toml()
    return f"""
universe = "waits"
seed = {args.seed}

[genome]
length = {args.genome_length}

[ea]
population = {args.population}
generations = {args.generations}

[islands]
count = {args.islands}
migration_interval = {args.interval}
migrants = 2
topology = "ring"
"""


class HostCPU:
    """The CPU seconds of the island hosts' processes (``ray::IslandHost``), read from ``/proc`` once a
    second by a thread of the bench (each host's newest figure kept, so a host that ends still counts):
    on a small machine, the simulated hosts' own CPU (breeding, Ray's traffic, part writes) competes
    with the waits, so it is as much part of the engine's cost as the driver's."""

    def __init__(self) -> None:
        self.seconds: dict[int, float] = {}
        self._stop = False
        self._tick = os.sysconf("SC_CLK_TCK")
        import threading

        self._thread = threading.Thread(target=self._watch, name="bench-host-cpu", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> float:
        """Stop reading; the hosts' CPU seconds, all together."""
        self._read()
        self._stop = True
        self._thread.join(timeout=5)
        return sum(self.seconds.values())

    def _watch(self) -> None:
        while not self._stop:
            self._read()
            time.sleep(1.0)

    def _read(self) -> None:
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                if not (entry / "cmdline").read_bytes().startswith(b"ray::IslandHost"):
                    continue
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            self.seconds[int(entry.name)] = (int(fields[11]) + int(fields[12])) / self._tick


class Instruments:
    """Timings and bytes the bench records in the driver, by wrapping the coordinator's methods."""

    def __init__(self) -> None:
        self.commits: list[float] = []
        self.received_bytes = 0
        self.overhead = 0.0
        self.compactions: list[float] = []   # seconds of each compaction (after a commit, same thread)
        self.traced: list[float] = []   # the driver's traced memory (MiB) after each commit

    def install(self) -> None:
        from genr8_dist.distributed import coordinator

        instruments = self
        commit = coordinator.Coordinator._commit

        def timed_commit(self: Any, *a: Any, **k: Any) -> Any:
            t = time.perf_counter()
            try:
                return commit(self, *a, **k)
            finally:
                instruments.commits.append(time.perf_counter() - t)
                if tracemalloc.is_tracing():
                    instruments.traced.append(tracemalloc.get_traced_memory()[0] / 2**20)

        coordinator.Coordinator._commit = timed_commit  # type: ignore[method-assign]
        compact = coordinator.Coordinator._compact

        def timed_compact(self: Any) -> bool:
            t = time.perf_counter()
            done = compact(self)
            if done:
                instruments.compactions.append(time.perf_counter() - t)
            return done

        coordinator.Coordinator._compact = timed_compact  # type: ignore[method-assign]
        receive = coordinator.Pipeline.receive

        def counted_receive(self: Any, island: int, g: int, population: Any, *a: Any, **k: Any) -> Any:
            t = time.perf_counter()
            instruments.received_bytes += len(pickle.dumps(population, protocol=5))
            instruments.overhead += time.perf_counter() - t
            return receive(self, island, g, population, *a, **k)

        coordinator.Pipeline.receive = counted_receive  # type: ignore[method-assign]


def timeline_figures(folder: Path, cpus: int) -> dict[str, Any]:
    """Where the CPUs' time went (``--timeline``), from every wait's log line (``GENR8_WAITS_LOG``):
    ``waited_s`` (the seconds slept, all waits together, / the CPUs: ``ideal_s`` plus what sleeping
    overshot, which the machine's load and the hosts' other threads cause), ``overshoot_ms_mean`` and
    ``overshoot_ms_p99`` (a wait's sleep past what it asked for), ``waits_span_s`` (first wait's start
    to last wait's end), ``idle_share`` (the share of the CPUs' seconds in that span with no wait on
    them) and ``tail_s`` (the seconds from the last moment at least 90% of the CPUs were waiting to
    the end: the islands that finish after the rest, each held by its own chain of long waits)."""
    starts, ends, asked = [], [], []
    for path in sorted(folder.glob("*.txt")):
        for line in path.read_text(encoding="ascii").splitlines():
            a, b, s = map(float, line.split())
            starts.append(a)
            ends.append(b)
            asked.append(s)
    if not starts:
        return {}
    begin, finish = min(starts), max(ends)
    overshoot = [max(0.0, b - a - s) for a, b, s in zip(starts, ends, asked, strict=True)]
    events = sorted([(a, 1) for a in starts] + [(b, -1) for b in ends])
    busy, running, last, full_until = 0.0, 0, begin, begin
    for t, step in events:
        busy += min(running, cpus) * (t - last)
        if running >= 0.9 * cpus:
            full_until = t
        running += step
        last = t
    span = finish - begin
    return {
        "waited_s": sum(b - a for a, b in zip(starts, ends, strict=True)) / cpus,
        "overshoot_ms_mean": 1e3 * statistics.fmean(overshoot),
        "overshoot_ms_p99": 1e3 * _percentile(overshoot, 0.99),
        "waits_span_s": span,
        "idle_share": 1.0 - busy / (cpus * span) if span > 0 else 0.0,
        "tail_s": finish - full_until,
    }


def run(args: argparse.Namespace) -> dict[str, Any]:
    """One simulated run; returns the figures."""
    os.environ["GENR8_PLUGINS"] = str(PLUGINS)
    os.environ["GENR8_WAITS_SCALE"] = repr(args.scale)
    import ray
    from ray.cluster_utils import Cluster

    from genr8_dist.distributed.session import RunOptions, start_run
    from genr8_dist.store import RunStore

    work = Path(tempfile.mkdtemp(prefix="genr8-scale-", dir=args.tmp))
    config_path = work / "scale.toml"
    config_path.write_text(config_toml(args))
    run_dir = work / "run"
    os.environ.pop("GENR8_WAITS_LOG", None)
    if args.timeline:
        (work / "waits").mkdir()
        os.environ["GENR8_WAITS_LOG"] = str(work / "waits")
    load_before = os.getloadavg()
    t0 = time.perf_counter()
    per_node = args.cpus / args.nodes
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": per_node})
    instruments = Instruments()
    instruments.install()
    try:
        for _ in range(args.nodes - 1):
            cluster.add_node(num_cpus=per_node)
        cluster.wait_for_nodes()
        ray.init(address=cluster.address, logging_level="ERROR", log_to_driver=False)
        if args.trace_memory:
            tracemalloc.start()
        hosts_cpu = HostCPU()
        hosts_cpu.start()
        cpu0 = time.process_time()
        profiler = cProfile.Profile() if args.profile else None
        if profiler is not None:
            profiler.enable()
        summary = start_run(config_path, str(run_dir),
                            RunOptions(quiet=True, schedule_timeout=600.0, host_cpus=args.host_cpus),
                            out=io.StringIO())
        if profiler is not None:
            profiler.disable()
            profiler.dump_stats(args.profile)
            pstats.Stats(profiler, stream=sys.stderr).sort_stats("tottime").print_stats(25)
        driver_cpu = time.process_time() - cpu0
        host_seconds = hosts_cpu.stop()
        total = time.perf_counter() - t0
    finally:
        ray.shutdown()
        cluster.shutdown()
    load_after = os.getloadavg()
    store = RunStore.open(str(run_dir))
    # what each stored evaluation cost: its wait, or under --real the seconds it took where it ran
    seconds = "eval_seconds" if args.real else "crit_wait"
    table = store.individuals(columns=["island", "generation", seconds, "grow_seconds"])
    scale = 1.0 if args.real else args.scale
    waits = table.column(seconds).to_pylist()
    grown = table.column("grow_seconds").to_pylist()
    waited = sum(w for w, g in zip(waits, grown, strict=True) if w is not None and g > 0) * scale
    longest: dict[tuple[int, int], float] = {}   # (island, generation) -> its longest evaluation
    for i, g, w, grew in zip(table.column("island").to_pylist(), table.column("generation").to_pylist(),
                             waits, grown, strict=True):
        if w is not None and grew > 0:
            longest[(i, g)] = max(longest.get((i, g), 0.0), w * scale)
    chains: dict[int, float] = {}
    for (i, _), w in longest.items():
        chains[i] = chains.get(i, 0.0) + w
    critical = max(chains.values(), default=0.0)
    rows = table.num_rows
    timeline = timeline_figures(work / "waits", args.cpus) if args.timeline else {}
    shutil.rmtree(work, ignore_errors=True)
    wall = summary.wall_seconds
    ideal = waited / args.cpus
    driver_busy = max(0.0, wall - summary.wait_seconds - instruments.overhead)
    commits = instruments.commits
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    engine_cpu = host_seconds + max(0.0, driver_cpu - instruments.overhead)
    return {
        "real": args.real or "", "islands": args.islands, "population": args.population, "cpus": args.cpus,
        "nodes": args.nodes, "generations": args.generations, "interval": args.interval, "scale": args.scale,
        "host_cpus": args.host_cpus,
        "hosts": summary.hosts, "rows": rows, "epochs": len(commits),
        "rows_per_epoch": rows / len(commits) if commits else 0.0,
        "wall_s": wall, "startup_s": total - wall, "ideal_s": ideal,
        "efficiency": ideal / wall if wall > 0 else 0.0,
        "critical_s": critical, "efficiency_bound": ideal / max(ideal, critical) if ideal > 0 else 0.0,
        "driver_cpu_s": driver_cpu - instruments.overhead,
        "driver_cpu_per_epoch_s": (driver_cpu - instruments.overhead) / len(commits) if commits else 0.0,
        "hosts_cpu_s": host_seconds, "hosts_cpu_per_row_ms": 1e3 * host_seconds / rows if rows else 0.0,
        "machine_cores": cores,
        "efficiency_machine_bound": ideal / max(ideal, engine_cpu / cores) if ideal > 0 else 0.0,
        "coordinator_share": driver_busy / wall if wall > 0 else 0.0,
        "coordinator_cpu_share": max(0.0, driver_cpu - instruments.overhead) / wall if wall > 0 else 0.0,
        "store_s": summary.store_seconds,
        "commit_p50_s": statistics.median(commits) if commits else 0.0,
        "commit_p99_s": _percentile(commits, 0.99), "commit_max_s": max(commits, default=0.0),
        "compactions": len(instruments.compactions),
        "compaction_max_s": max(instruments.compactions, default=0.0),
        "driver_bytes_per_row": instruments.received_bytes / rows if rows else 0.0,
        "driver_peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "load_before": [round(x, 2) for x in load_before], "load_after": [round(x, 2) for x in load_after],
        "status": summary.status,
        **timeline,
        **({"driver_traced_mb_by_commit": [round(x, 2) for x in instruments.traced]}
           if args.trace_memory else {}),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--islands", type=int, default=None, help="islands (waits: 16)")
    parser.add_argument("--population", type=int, default=None, help="per island (waits: 50)")
    parser.add_argument("--cpus", type=int, default=16, help="Ray's logical CPUs, all nodes together")
    parser.add_argument("--nodes", type=int, default=1, help="Ray nodes (raylets) on this machine")
    parser.add_argument("--generations", type=int, default=None, help="the run's last generation (waits: 10)")
    parser.add_argument("--interval", type=int, default=None, help="islands.migration_interval (waits: 5)")
    parser.add_argument("--real", default=None, metavar="CONFIG",
                        help="evolve this run configuration with real evaluation instead of waits")
    parser.add_argument("--sweep", default=None, metavar="CPUS",
                        help="comma-separated CPU counts: the same run at each (e.g. 1,2,4,8,16)")
    parser.add_argument("--scale", type=float, default=1.0,
                        help="multiplies every wait (1: the measured distribution)")
    parser.add_argument("--host-cpus", type=int, default=1,
                        help="CPUs of one simulated host: it evaluates that many waits at once (threads of "
                             "one process, so Ray's per-process cost is paid once per N CPUs)")
    parser.add_argument("--genome-length", type=int, default=20)
    parser.add_argument("--seed", type=int, default=None, help="the run's seed (waits: 1)")
    parser.add_argument("--tmp", default=None, help="where the run directory goes (a temporary folder)")
    parser.add_argument("--json", default=None, help="write the figures to this file as one JSON object")
    parser.add_argument("--timeline", action="store_true",
                        help="log every wait and say where the CPUs' time went (waited_s, overshoot, "
                             "idle_share, tail_s)")
    parser.add_argument("--trace-memory", action="store_true",
                        help="trace the driver's memory (tracemalloc; slows it): its size after each commit")
    parser.add_argument("--profile", default=None,
                        help="profile the driver's thread (cProfile) into this file; print its top functions")
    args = parser.parse_args(argv)
    if args.real is None:
        for key, value in WAITS_DEFAULTS.items():
            if getattr(args, key) is None:
                setattr(args, key, value)
    elif not Path(args.real).is_file():
        parser.error(f"--real: no run configuration at {args.real}")
    counts = [args.cpus]
    if args.sweep:
        try:
            counts = [int(c) for c in args.sweep.split(",")]
        except ValueError:
            parser.error(f"--sweep: {args.sweep!r} is not a comma-separated list of CPU counts")
    if min(counts) < 1 or args.nodes < 1 or min(counts) < args.nodes:
        parser.error("--cpus (each --sweep count) and --nodes must be at least 1, the CPUs at least --nodes")
    sweep = []
    for cpus in counts:
        args.cpus = cpus
        figures = run(args)
        sweep.append(figures)
        width = max(len(k) for k in figures)
        for key, value in figures.items():
            shown = f"{value:.4g}" if isinstance(value, float) else value
            print(f"{key:<{width}}  {shown}")
        print(flush=True)
    if args.sweep:
        print(sweep_table(sweep))
    if args.json:
        Path(args.json).write_text(json.dumps({"sweep": sweep} if args.sweep else sweep[0], indent=1) + "\n")
    return 0


def sweep_table(sweep: list[dict[str, Any]]) -> str:
    """The sweep's figures at each CPU count, with ``speedup`` and ``scaling_efficiency`` over the first
    count added to each (``speedup`` / (cpus / first cpus))."""
    first = sweep[0]
    lines = ["| cpus | hosts | rows | wall s | speedup | scaling efficiency | efficiency | coordinator share "
             "| commit p99 s | driver bytes/row |", "|" + " --- |" * 10]
    for f in sweep:
        f["speedup"] = first["wall_s"] / f["wall_s"] if f["wall_s"] > 0 else 0.0
        f["scaling_efficiency"] = f["speedup"] / (f["cpus"] / first["cpus"])
        lines.append(f"| {f['cpus']} | {f['hosts']} | {f['rows']} | {f['wall_s']:.2f} | {f['speedup']:.2f} "
                     f"| {f['scaling_efficiency']:.3f} | {f['efficiency']:.3f} "
                     f"| {f['coordinator_share']:.4f} | {f['commit_p99_s']:.3f} "
                     f"| {f['driver_bytes_per_row']:.1f} |")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
