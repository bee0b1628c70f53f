"""Starting, resuming and driving a run: connect to Ray, start the island hosts, run the coordinator.

``start_run`` and ``resume_run`` are what ``genr8 run`` and ``genr8 resume`` call. Nothing is written to
the run directory before Ray answers and the island hosts are scheduled, so a wrong ``--address`` or a
cluster without room leaves the directory exactly as it was.

Ray: with no address (and no ``RAY_ADDRESS`` in the environment, which ``ray job submit`` sets) a local
Ray starts inside the command and stops with it (the embedded default). ``address="auto"`` joins the
cluster running on this machine, ``"HOST:PORT"`` a cluster's head, ``"ray://HOST:PORT"`` a cluster
through Ray Client. If Ray is already initialised in this process (a notebook, the tests), it is used
as it is and left running.
"""

from __future__ import annotations

import contextlib
import os
import socket
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from genr8_dist.errors import Genr8Error, RunError, StoreError

if TYPE_CHECKING:
    from contextlib import AbstractContextManager

    from genr8_dist.config import RunConfig
    from genr8_dist.distributed.coordinator import Coordinator, RunSummary, StopRequest
    from genr8_dist.grammar.source import UniverseSource
    from genr8_dist.store import RunStore
    from genr8_dist.store.pending import RunLock

__all__ = ["RunOptions", "connect_ray", "drive", "hold_run_lock", "latest_config", "resume_run", "start_run",
           "stored_universes"]

CONNECT_TIMEOUT = 5.0


@dataclass(frozen=True, slots=True)
class RunOptions:
    """How to run: where Ray is, how many CPUs a local Ray gets, and what to print."""

    address: str | None = None
    num_cpus: int | None = None           # a local Ray's CPUs (default: all of this machine's); on a
                                          # cluster, the CPUs the run asks for (its autoscaler adds nodes)
    quiet: bool = False
    schedule_timeout: float = 60.0        # seconds to wait for the island hosts to start
    max_hosts: int | None = None          # at most this many island hosts (default: one per free CPU)
    host_cpus: int = 1                    # the CPUs of one island host: it evaluates that many genomes at
                                          # once (threads: for a phenotype that waits or releases the GIL)
    trust_hooks: bool = False             # run the Python code a run directory carries (resume)
    dashboard: bool | None = None         # Ray's dashboard: on (a local Ray starts it), off, or None:
                                          # a cluster's URL printed when its head runs one
    exits_after: bool = False             # the caller exits once the run returns (a command): SIGINT
                                          # and SIGTERM stay ignored from then on (interrupts)


def _host_port(address: str) -> tuple[str, int] | None:
    rest = address.split("://", 1)[1] if "://" in address else address
    host, sep, port = rest.rstrip("/").rpartition(":")
    if not sep or not port.isdigit():
        return None
    return host.strip("[]") or "127.0.0.1", int(port)


def _probe(address: str) -> None:
    """Refuse at once (``RunError``) an address where nothing accepts a connection."""
    where = _host_port(address)
    if where is None:
        raise RunError(f"--address {address!r}: expected 'auto', HOST:PORT or ray://HOST:PORT")
    try:
        with socket.create_connection(where, timeout=CONNECT_TIMEOUT):
            pass
    except OSError as exc:
        raise RunError(
            f"--address {address}: no Ray cluster answers there ({exc.strerror or exc}); "
            "start one (cluster/README.md) or leave --address out to run on a local Ray"
        ) from None


def _find_local_cluster() -> str:
    """The address of the cluster ``ray start`` started on this machine (what ``--address auto`` means),
    or ``RunError`` when there is none; a stale record of a stopped one is refused by the probe."""
    try:
        from ray._private.utils import read_ray_address
    except ImportError:  # pragma: no cover - Ray moved it: let ray.init resolve "auto" itself
        return "auto"
    found = read_ray_address()
    if not found:
        raise RunError("--address auto: no Ray cluster was started on this machine (`ray start --head`, "
                       "or cluster/local_cluster.sh start); leave --address out to run on a local Ray")
    return str(found)


def _token_auth_like_ray_start() -> None:
    """Use Ray's token authentication when a token exists and ``RAY_AUTH_MODE`` is unset, as
    ``ray start --head`` does: Ray 2.5x/2.6x clients joining such a cluster otherwise fail to
    authenticate (they switch to token mode after Ray's configuration is read, so this must run before
    ``import ray``)."""
    token = os.environ.get("RAY_AUTH_TOKEN_PATH") or os.path.join(os.path.expanduser("~"), ".ray",
                                                                   "auth_token")
    if "RAY_AUTH_MODE" not in os.environ and (os.environ.get("RAY_AUTH_TOKEN") or os.path.isfile(token)):
        os.environ["RAY_AUTH_MODE"] = "token"


def _signal_handlers() -> dict[int, Any]:
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    return {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}


def _restore_signal_handlers(handlers: dict[int, Any]) -> None:
    import signal

    for sig, handler in handlers.items():
        signal.signal(sig, handler if handler is not None else signal.SIG_DFL)


def _preload() -> None:
    """Import what a run needs once Ray is up: the coordinator, the hosts, the store and pyarrow."""
    import pyarrow.compute
    import pyarrow.parquet  # noqa: F401  (the store imports them at its first commit: 0.1-0.2 s)

    import genr8_dist.distributed.coordinator
    import genr8_dist.distributed.hosts
    import genr8_dist.evolution
    import genr8_dist.store  # noqa: F401


def _meanwhile(work: Callable[[], None] | None) -> threading.Thread | None:
    """``work`` in a thread of its own (its errors are left for the main thread to meet again)."""
    if work is None:
        return None

    def run() -> None:
        with contextlib.suppress(Exception):   # what failed here fails again where it is needed
            work()

    thread = threading.Thread(target=run, name="genr8-meanwhile", daemon=True)
    thread.start()
    return thread


# A local Ray on a loaded machine can take longer than Ray's own waits (30 s for the GCS's port, about
# 20 s for the GCS to answer, 60 s for a worker to register): the local Ray gets these, unless the
# environment already sets them. The raylet's own 30 s registration wait is fixed in Ray: a start that
# still fails is tried again once, after a pause, then refused in one line.
PATIENT_RAY_ENV = {
    "RAY_gcs_server_port_wait_time_s": "120",
    "RAY_worker_register_timeout_seconds": "180",
}
PATIENT_GCS_RETRIES = 120
START_ATTEMPTS = 2
RETRY_PAUSE = 3.0


@contextmanager
def _patient_start() -> Iterator[None]:
    """Ray's start-up waits raised (``PATIENT_RAY_ENV``) while a local Ray starts; put back after."""
    from ray._private import ray_constants

    saved = {name: os.environ.get(name) for name in PATIENT_RAY_ENV}
    retries = ray_constants.NUM_REDIS_GET_RETRIES
    for name, value in PATIENT_RAY_ENV.items():
        os.environ.setdefault(name, value)
    if "RAY_NUM_REDIS_GET_RETRIES" not in os.environ:
        ray_constants.NUM_REDIS_GET_RETRIES = max(retries, PATIENT_GCS_RETRIES)
    try:
        yield
    finally:
        ray_constants.NUM_REDIS_GET_RETRIES = retries
        for name, before in saved.items():
            if before is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = before


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0].strip() if text else type(exc).__name__


def _init_with_retry(ray: Any, address: str | None, kwargs: dict[str, Any]) -> Any:
    """``ray.init(**kwargs)``, tried ``START_ATTEMPTS`` times; then a one-line ``RunError`` saying why
    and what to do. Ray raises a plain ``Exception`` for a node that timed out during start-up, so
    every ``Exception`` is met here (a SIGTERM's ``SystemExit`` is the caller's). Returns Ray's
    context."""
    import time

    cause = ""
    for attempt in range(1, START_ATTEMPTS + 1):
        try:
            return ray.init(**kwargs)
        except Exception as exc:   # Ray's start-up failures have no class of their own
            cause = _first_line(exc)
            with contextlib.suppress(Exception):
                ray.shutdown()   # what a half-started Ray left: its processes, its global state
        if attempt < START_ATTEMPTS:
            time.sleep(RETRY_PAUSE)
    tries = f"{START_ATTEMPTS} tries" if START_ATTEMPTS > 1 else "1 try"
    if address is None:
        raise RunError(f"a new local Ray did not start ({tries}; Ray said: {cause}); this machine may be "
                       "too busy: try again when it is quieter, or give the run fewer CPUs with --cpus N")
    raise RunError(f"cannot connect to Ray at {address} ({tries}; Ray said: {cause}); check that the "
                   f"cluster is up (`ray status --address {address}`), or leave --address out to run on "
                   "a local Ray")


@contextmanager
def connect_ray(address: str | None = None, num_cpus: int | None = None, *,
                meanwhile: Callable[[], None] | None = None, dashboard: bool = False,
                on_dashboard: Callable[[str | None], None] | None = None) -> Iterator[Any]:
    """Ray, connected as described in the module docstring; disconnects on leaving only if it connected.

    ``meanwhile`` runs in a thread while Ray starts or connects (``ray.init`` mostly waits for Ray's
    processes): a run's own start-up work (imports) then costs no time of its own. ``dashboard``: a
    local Ray starts its dashboard (needs ``ray[default]``); ``on_dashboard`` is told the dashboard's
    URL once connected (``None`` when there is none)."""
    import logging

    if "ray" not in sys.modules and (address is not None or os.environ.get("RAY_ADDRESS")):
        _token_auth_like_ray_start()
    import ray

    if address == "auto" and not ray.is_initialized():
        address = _find_local_cluster()
    if address is not None and address != "auto":
        _probe(address)
    if ray.is_initialized():
        yield ray
        return
    if address is None:
        address = os.environ.get("RAY_ADDRESS") or None
        if address is not None and address != "auto" and "://" not in address:
            _probe(address)
    kwargs: dict[str, Any] = {"logging_level": logging.ERROR, "log_to_driver": False}
    handlers = _signal_handlers()
    helper = _meanwhile(meanwhile)
    # Ray's SIGTERM handler exits by raising SystemExit; landing inside a fork callback (logging's lock
    # release) the exit is swallowed and printed as "Exception ignored". Keep it, and honour it below.
    swallowed: list[BaseException] = []
    previous_hook = sys.unraisablehook

    def keep_exits(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, (SystemExit, KeyboardInterrupt)):
            swallowed.append(unraisable.exc_value)
        else:
            previous_hook(unraisable)

    sys.unraisablehook = keep_exits
    try:
        if address is None:
            # "local": a new Ray of our own, even when `ray start` left a cluster (or its address file);
            # its processes end with this one, even when it is killed (distributed/reaper.py)
            from genr8_dist.distributed.reaper import start_reaper

            start_reaper()
            with _patient_start():
                context = _init_with_retry(ray, None, dict(address="local", num_cpus=num_cpus,
                                                           include_dashboard=dashboard, **kwargs))
        else:
            context = _init_with_retry(ray, address, dict(address=address, **kwargs))
    except SystemExit:  # SIGTERM while Ray starts: its own handler exits; nothing is written yet
        ray.shutdown()
        raise KeyboardInterrupt("SIGTERM while Ray was starting") from None
    finally:
        sys.unraisablehook = previous_hook
        _restore_signal_handlers(handlers)  # ray.init installs a SIGTERM handler that exits at once
        if helper is not None:
            helper.join()
    if swallowed:
        ray.shutdown()
        raise KeyboardInterrupt("SIGTERM while Ray was starting")
    if on_dashboard is not None:
        url = getattr(context, "dashboard_url", None)
        on_dashboard(f"http://{url}" if url and "://" not in url else (url or None))
    try:
        yield ray
    finally:
        ray.shutdown()


def joined_address(requested: str | None) -> str:
    """The cluster the connected Ray belongs to, as the run's ``start``/``resume`` event records it:
    ``"local"`` for a Ray this command started itself, else the GCS address actually joined (what
    ``auto``, ``RAY_ADDRESS`` from ``ray job submit``, or ``--address`` led to), from Ray's runtime
    context; the requested address when Ray does not say (a ``ray://`` client)."""
    given = requested or os.environ.get("RAY_ADDRESS") or None
    if given is None:
        return "local"
    import ray

    try:
        gcs = ray.get_runtime_context().gcs_address
    except Exception:  # a client connection or an older Ray: no runtime context address
        gcs = None
    return str(gcs) if gcs else given


def _local_path(run_dir: str) -> Path | None:
    return None if "://" in str(run_dir) else Path(run_dir)


def _check_new_run_dir(run_dir: str) -> None:
    """Refuse, before anything starts, a local run directory that holds a run or anything else (a
    creation that stopped before its first commit is finished by ``RunStore.create``)."""
    from genr8_dist.store._fs import resolve
    from genr8_dist.store.runstore import half_created

    path = _local_path(run_dir)
    if path is None or not path.exists():
        return
    if not path.is_dir():
        raise StoreError(f"{run_dir}: exists and is not a directory; choose another --run-dir")
    state = half_created(resolve(run_dir))
    if state == "run":
        raise StoreError(
            f"{run_dir}: already holds a run; go on with `genr8 resume {run_dir}` or choose another --run-dir"
        )
    if state == "damaged":
        raise StoreError(f"{run_dir}: holds a damaged run (data but no intact manifest); choose another "
                         "--run-dir")
    if state == "foreign":
        raise StoreError(f"{run_dir}: exists and is not empty; choose another --run-dir")


def stored_universes(store: RunStore) -> list[UniverseSource]:
    """The universe of every configuration version of the run that can be read (a damaged version is
    left to ``repair``), without running any of their code."""
    sources: list[UniverseSource] = []
    try:
        versions = store.configs()
    except StoreError:  # a damaged version: the one the run was created with, until repair
        versions = [store.config_for(0)]
    for version in versions:
        try:
            config = store.config(version)
        except Genr8Error:  # a damaged version: verify() reports it, repair() drops it
            continue
        if config.universe_source not in sources:
            sources.append(config.universe_source)
    return sources


def latest_config(store: RunStore) -> RunConfig:
    """The run's newest configuration version, as a ``RunConfig``."""
    newest = store.configs()[-1]
    return store.config(newest)


def _creation_config(store: RunStore) -> RunConfig:
    """The configuration a damaged run was created with (``StoreError`` from ``repair`` when that very
    file is damaged: the run has no intact state to fall back to)."""
    try:
        first = store.config_for(0)
    except StoreError:
        store.repair()
        raise
    return store.config(first)


def _refuse_if_running(store: RunStore, holder: dict[str, Any] | None = None) -> None:
    """``RunError`` when a ``run``-role process holds the run's lock (``holder``: who, when known)."""
    if holder is None:
        holder = store.running()
        if holder is None or holder.get("role") != "run":
            return
    raise _refuse_running(store.path, holder)


def _refuse_running(where: str, holder: dict[str, Any] | None) -> RunError:
    holder = holder or {}
    return RunError(f"{where}: the run is running already (pid {holder.get('pid', '?')} on "
                    f"{holder.get('host', '?')}); `genr8 edit` or the studio can steer it meanwhile")


def _lock_new_run(run_dir: str) -> RunLock:
    """The lock of the run about to be created in ``run_dir``, taken before anything is written there,
    so that of two drivers starting the same run at once the second is refused and writes nothing."""
    from genr8_dist.store._fs import resolve
    from genr8_dist.store.pending import RunLock, lock_holder

    rfs = resolve(run_dir)
    if rfs.local_root is not None:
        rfs.makedirs()
    lock = RunLock(rfs, "run")
    if not lock.acquire():
        raise _refuse_running(rfs.show(), lock_holder(rfs))
    return lock


@contextmanager
def hold_run_lock(store: RunStore, lock: RunLock | None = None) -> Iterator[None]:
    """Hold the run's lock while the run runs (``store/pending.py``): ``genr8 edit`` and the studio
    then queue their interventions for the coordinator instead of writing. Refuses a run that another
    process is running. ``lock``: the run's lock, already taken (``_lock_new_run``)."""
    if lock is not None:
        store.writer_lock = lock
    else:
        lock = store.lock("run")
        if not lock.acquire():
            raise _refuse_running(store.path, store.running())
    try:
        yield
    finally:
        lock.release()


def drive(store: RunStore, options: RunOptions, *, out: TextIO | None = None,
          on_generation: Callable[[Coordinator, int], None] | None = None,
          on_commit: Callable[[Coordinator, Any], None] | None = None,
          stop: StopRequest | None = None, hosts: Any = None,
          on_island: Callable[[Coordinator, int, int, Any], None] | None = None) -> RunSummary:
    """Run the coordinator on ``store`` until the run completes or is interrupted (signals caught);
    the hooks are the coordinator's."""
    _preload()
    from genr8_dist.distributed.coordinator import Coordinator, StopRequest
    from genr8_dist.distributed.hosts import HostPool
    from genr8_dist.distributed.interrupts import stop_on_signals
    from genr8_dist.distributed.progress import ProgressDisplay

    out = out if out is not None else sys.stdout
    own_hosts = hosts is None
    if hosts is None:
        latest = latest_config(store)
        hosts = HostPool(str(store.path), int(latest.islands.count), max_hosts=options.max_hosts,
                         host_cpus=options.host_cpus, timeout=options.schedule_timeout,
                         cpus=_cluster_cpus(options))
    stop = stop if stop is not None else StopRequest()
    live = store.live()   # the hosts write each island's completed generation there (advance's live)

    dropping = threading.Lock()

    def drop(after: Any) -> None:
        with dropping, contextlib.suppress(OSError):
            live.drop_committed(after)

    def committed(coordinator: Coordinator, after: Any) -> None:
        # deleting an epoch's live files (one per island and generation) is left to a thread
        threading.Thread(target=drop, args=(dict(after),), name="genr8-live", daemon=True).start()
        if on_commit is not None:
            on_commit(coordinator, after)

    try:
        progress = ProgressDisplay(total_generations=0, out=out, quiet=options.quiet)
        coordinator = Coordinator(store, hosts, stop=stop, on_generation=on_generation, on_commit=committed,
                                  on_island=on_island, live=True, progress=progress)

        def announce(text: str) -> None:   # above the progress table; said even when quiet
            if options.quiet:
                print(text, file=out, flush=True)
            else:
                progress.message(text)

        with stop_on_signals(stop, announce=announce):
            return coordinator.run()
    finally:
        with dropping:
            live.clear()
        if own_hosts:
            hosts.shutdown()


def _dashboard_options(options: RunOptions, out: TextIO) -> dict[str, Any]:
    """``connect_ray``'s dashboard arguments for ``options.dashboard`` (``--dashboard``): its URL
    printed when there is one; asked for and missing, a line saying why."""
    if options.dashboard:
        try:
            import aiohttp  # noqa: F401  (what ray[default] adds for the dashboard)
        except ImportError:
            raise RunError("--dashboard: Ray's dashboard needs ray[default]: "
                           "pip install 'ray[default]'") from None

    def say(url: str | None) -> None:
        if url:
            print(f"dashboard: {url}", file=out, flush=True)
        elif options.dashboard:
            print("dashboard: none on this cluster (its head starts one when it has ray[default])",
                  file=out, flush=True)

    return {"dashboard": bool(options.dashboard), "on_dashboard": None if options.dashboard is False else say}


def _cluster_cpus(options: RunOptions) -> int | None:
    """The CPUs a run on a cluster asks for (``--cpus`` with an address, or inside a Ray job); a local
    Ray is started with ``num_cpus`` instead."""
    joined = options.address is not None or bool(os.environ.get("RAY_ADDRESS"))
    return options.num_cpus if joined else None


def _stop_request(given: StopRequest | None) -> StopRequest:
    from genr8_dist.distributed.coordinator import StopRequest

    return given if given is not None else StopRequest()


def _signals_stop(stop: StopRequest, out: TextIO, options: RunOptions) -> AbstractContextManager[StopRequest]:
    """SIGINT and SIGTERM set ``stop`` while inside (``interrupts.stop_on_signals``); ignored after it
    where the caller exits once the run returns (``options.exits_after``)."""
    import signal

    from genr8_dist.distributed.interrupts import stop_on_signals

    return stop_on_signals(stop, announce=lambda text: print(text, file=out, flush=True),
                           then=signal.SIG_IGN if options.exits_after else None)


def _report(summary: RunSummary, run_dir: str, out: TextIO) -> None:
    from genr8_dist.distributed.progress import format_duration

    committed = summary.committed
    low = min(committed.values()) if committed else -1
    rate = summary.individuals / summary.wall_seconds if summary.wall_seconds > 0 else 0.0
    timing = (f"{summary.individuals} individuals in {format_duration(summary.wall_seconds)}"
              f" ({rate:.1f}/s)")
    if summary.finished:
        print(f"run complete: generations 0..{summary.last_generation} of {len(committed)} island(s) "
              f"committed; {timing}", file=out)
        print(f"results: {run_dir}", file=out)
        commands = _history_commands(run_dir)
        if commands:
            print("look at them: " + "   ".join(commands), file=out)
    else:
        spread = sorted(set(committed.values()))
        at = f"generation {low}" if len(spread) == 1 else f"generations {spread[0]}..{spread[-1]}"
        if low < 0 and len(spread) <= 1:
            print(f"interrupted before generation 0 was committed; {timing}", file=out)
        else:
            print(f"interrupted: islands committed up to {at}; {timing}", file=out)
        print(f"resume with: genr8 resume {run_dir}", file=out)
    out.flush()


def _history_commands(run_dir: str) -> list[str]:
    """The ``genr8`` commands that show a run's results."""
    return [f"genr8 top {run_dir}", f"genr8 report {run_dir}", f"genr8 history {run_dir}"]


def start_run(config_path: str | os.PathLike[str], run_dir: str, options: RunOptions,
              *, out: TextIO | None = None, **hooks: Any) -> RunSummary:
    """``genr8 run``: a new run of the configuration in ``config_path`` in the new ``run_dir``."""
    from genr8_dist.config import load_config
    from genr8_dist.distributed.hosts import HostPool
    from genr8_dist.grammar.discovery import consent_for_new_run
    from genr8_dist.grammar.universe import build_universe
    from genr8_dist.store import RunStore

    out = out if out is not None else sys.stdout
    config = load_config(os.fspath(config_path))
    _check_new_run_dir(run_dir)
    consent_for_new_run(config.universe_source, trust_flag=options.trust_hooks,
                        command=f"run {config_path} --run-dir {run_dir}")
    if config.universe_source.code_digest:  # consented now: read again, so its phenotype sets the criteria
        config = load_config(config_path)
    build_universe(config.universe_source, check=True)   # a plugin's code, checked before anything is written
    hooks["stop"] = stop = _stop_request(hooks.get("stop"))
    # signals are caught from the start to the end of the shutdown: one during Ray's start-up stops the
    # run before its first epoch, one after the last commit changes nothing (the run is complete)
    with _signals_stop(stop, out, options), \
            connect_ray(options.address, options.num_cpus, meanwhile=_preload,
                        **_dashboard_options(options, out)), ExitStack() as stack:
        hosts = HostPool(os.path.abspath(run_dir) if _local_path(run_dir) else run_dir,
                         int(config.islands.count), max_hosts=options.max_hosts,
                         host_cpus=options.host_cpus, timeout=options.schedule_timeout,
                         cpus=_cluster_cpus(options))
        try:
            lock = _lock_new_run(run_dir)
            stack.callback(lock.release)
            store = RunStore.create(run_dir, config.to_toml())
            stack.enter_context(hold_run_lock(store, lock))
            store.record_event("start", generation=0, detail={
                "config": str(config_path), "islands": config.islands.count, "hosts": hosts.size,
                "address": joined_address(options.address)})
            if not options.quiet:
                print(f"run {run_dir}: {config.islands.count} island(s) x {config.ea.population} "
                      f"individuals, generations 0..{config.ea.generations}, on {hosts.size} Ray "
                      f"host(s); Ctrl-C stops it cleanly", file=out, flush=True)
            summary = drive(store, options, out=out, hosts=hosts, **hooks)
        finally:
            hosts.shutdown()
    _report(summary, run_dir, out)
    return summary


def resume_run(run_dir: str, options: RunOptions, *, out: TextIO | None = None, hosts: Any = None,
               **hooks: Any) -> RunSummary:
    """``genr8 resume``: go on with the run in ``run_dir`` from its last committed generation (on
    ``hosts``, a ``HostPool`` of an earlier run, rebound to this one, when given)."""
    from genr8_dist.distributed.hosts import HostPool
    from genr8_dist.grammar.discovery import consent_for_stored
    from genr8_dist.store import RunStore

    out = out if out is not None else sys.stdout
    store = RunStore.open(run_dir)
    problems = store.verify()
    consent_for_stored(stored_universes(store), trust_flag=options.trust_hooks,
                       command=f"resume {run_dir}")
    # A damaged run is repaired once Ray and the hosts are up (nothing is written before); until then
    # its newest configuration may be the damaged file, so read the one the run was created with
    # (islands.count cannot change during a run). Damage to that one leaves nothing to fall back to,
    # which repair() says, naming the file, without writing anything.
    latest = _creation_config(store) if problems else latest_config(store)
    committed = store.committed_generations()
    n = int(latest.islands.count)
    last = int(latest.ea.generations)
    if not problems and committed and min(committed.get(i, -1) for i in range(n)) >= last:
        print(f"{run_dir}: the run is complete (generation {last}); nothing to resume. "
              f"`genr8 edit {run_dir} --generations N` adds N generations.", file=out)
        from genr8_dist.distributed.coordinator import RunSummary

        summary = RunSummary(status="complete", committed=dict(committed), last_generation=last)
        return summary
    hooks["stop"] = stop = _stop_request(hooks.get("stop"))
    _refuse_if_running(store)   # at once, before Ray starts; the lock itself is taken once Ray is up
    with _signals_stop(stop, out, options), \
            connect_ray(options.address, options.num_cpus, meanwhile=_preload,
                        **_dashboard_options(options, out)), hold_run_lock(store):
        own = hosts is None
        if own:
            hosts = HostPool(str(store.path), n, max_hosts=options.max_hosts,
                             host_cpus=options.host_cpus, timeout=options.schedule_timeout,
                             cpus=_cluster_cpus(options))
        else:
            hosts.rebind(str(store.path), n)
        try:
            if problems:
                for problem in problems:
                    print(f"damaged: {problem}", file=out, flush=True)
                store.repair()
                print(f"repaired: {store.last_repair}", file=out, flush=True)
                consent_for_stored(stored_universes(store), trust_flag=options.trust_hooks,
                                   command=f"resume {run_dir}")
            else:
                store.collect_garbage()  # what crashed writers left: orphaned files, stale temporaries
            if store.upgrade():  # a run of layout 1: its folders become exact for any Parquet reader
                print(f"{run_dir}: upgraded to layout 2 (docs/run-store.md)", file=out, flush=True)
            if store.set_aside:
                from genr8_dist.store.foreign import describe

                print(describe(store.set_aside, run_dir), file=out, flush=True)
            committed = store.committed_generations()
            low = min(committed.get(i, -1) for i in range(n))
            store.record_event("resume", generation=max(0, low + 1), detail={
                "committed": {str(i): int(committed.get(i, -1)) for i in range(n)},
                "hosts": hosts.size, "address": joined_address(options.address)})
            if not options.quiet:
                print(f"resuming {run_dir} after generation {low} on {hosts.size} Ray host(s)",
                      file=out, flush=True)
            summary = drive(store, options, out=out, hosts=hosts, **hooks)
        finally:
            if own:
                hosts.shutdown()
    _report(summary, run_dir, out)
    return summary
