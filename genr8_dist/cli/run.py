"""``genr8 run``, ``resume``, ``repair`` and ``edit``: start a foray, go on with it, mend it, intervene.

Interruption, intervention and resumption (thesis 4.2): Ctrl-C (or SIGTERM, what ``ray job stop``
sends) stops a run after committing every complete generation and prints how to resume; ``genr8 edit``
records a new configuration version and injected individuals for the next generation; ``genr8 resume``
goes on from the last committed generation.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from genr8_dist.cli._args import int32

if TYPE_CHECKING:
    from genr8_dist.distributed.session import RunOptions

__all__ = ["register"]


def _ray_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--address", metavar="ADDRESS", default=None,
                        help="a Ray cluster to run on: 'auto' (the one on this machine), HOST:PORT or "
                             "ray://HOST:PORT; default: start a local Ray inside this command")
    parser.add_argument("--cpus", type=int, default=None, metavar="N",
                        help="CPUs of the local Ray (default: all of this machine's); with --address or "
                             "in a Ray job, the CPUs the run asks the cluster for (an autoscaler adds nodes)")
    parser.add_argument("--host-cpus", type=int, default=1, metavar="N",
                        help="CPUs of one island host, which evaluates N genomes at once in threads of one "
                             "process (for a phenotype that waits on something outside Python or releases "
                             "the GIL; default 1)")
    parser.add_argument("--quiet", action="store_true", help="print no progress lines, only the outcome")
    parser.add_argument("--dashboard", action=argparse.BooleanOptionalAction, default=None,
                        help="Ray's dashboard: a local Ray starts it (needs ray[default]) and its URL is "
                             "printed; default: the URL of a cluster's dashboard when it runs one, none "
                             "for a local Ray")
    _trust_option(parser)


def _trust_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--trust-hooks", action="store_true",
                        help="run the Python code (hooks.py) of the universe the run directory carries; "
                             "needed once per code digest on a machine that has not trusted it "
                             "(docs/run-store.md: the trust rule)")


def _options(args: argparse.Namespace) -> RunOptions:
    from genr8_dist.distributed.session import RunOptions
    from genr8_dist.errors import ConfigError

    if args.cpus is not None and args.cpus < 1:
        raise ConfigError(f"--cpus {args.cpus}: must be >= 1")
    host_cpus = int(getattr(args, "host_cpus", 1))
    if host_cpus < 1:
        raise ConfigError(f"--host-cpus {host_cpus}: must be >= 1")
    return RunOptions(address=args.address, num_cpus=args.cpus, quiet=args.quiet, host_cpus=host_cpus,
                      trust_hooks=bool(getattr(args, "trust_hooks", False)),
                      dashboard=getattr(args, "dashboard", None),
                      exits_after=bool(getattr(args, "exits", False)))


def _run(args: argparse.Namespace) -> int:
    from genr8_dist.distributed.session import start_run

    if not args.studio:
        start_run(args.config, args.run_dir, _options(args), out=sys.stdout)
        return 0
    from genr8_dist.cli.studio import start_studio, wait_for_interrupt
    from genr8_dist.config import load_config

    load_config(args.config)   # a wrong configuration is one line, before the studio says where it is
    studio = start_studio(args.run_dir, args.studio_host, args.studio_port, args.studio_token)
    try:
        start_run(args.config, args.run_dir, _options(args), out=sys.stdout)
        print(f"the studio stays open at {studio.url}; Ctrl-C closes it", flush=True)
        wait_for_interrupt()
    finally:
        studio.close()
    return 0


def _resume(args: argparse.Namespace) -> int:
    from genr8_dist.distributed.session import resume_run

    resume_run(args.run_dir, _options(args), out=sys.stdout)
    return 0


def _repair(args: argparse.Namespace) -> int:
    from genr8_dist.errors import StoreError
    from genr8_dist.store import RunStore

    store = RunStore.open(args.run_dir)
    problems = store.verify()
    if not problems:
        with store.lock("edit") as lock:
            if not lock.acquire():
                raise StoreError(f"{args.run_dir}: the run is running; repair it after it stops")
            upgraded = store.upgrade() if args.upgrade or store.manifest_layout >= 2 else False
        if upgraded:  # (layout 2: upgrade() only finishes a glob view a crash left one commit behind)
            print(f"{args.run_dir}: upgraded to layout 2 (commit {store.version}); any Parquet reader "
                  "now reads individuals/*.parquet and events/*.parquet exactly")
            return 0
        print(f"{args.run_dir}: intact (commit {store.version}); nothing to repair")
        if store.manifest_layout < 2:
            print(f"note: {args.run_dir} has layout 1; `genr8 repair --upgrade {args.run_dir}` converts it "
                  "so that any Parquet reader reads it exactly")
        return 0
    for problem in problems:
        print(f"damaged: {problem}")
    store.repair()
    print(f"repaired: {store.last_repair}")
    if args.upgrade and store.upgrade():
        print(f"{args.run_dir}: upgraded to layout 2 (commit {store.version})")
    if store.set_aside:
        from genr8_dist.store.foreign import describe

        print(describe(store.set_aside, args.run_dir))
    print(f"{args.run_dir}: now at commit {store.version}; islands committed up to "
          + ", ".join(f"{i}: {g}" for i, g in store.committed_generations().items()))
    return 0


def _edit(args: argparse.Namespace) -> int:
    from genr8_dist.distributed.intervene import Edit, apply_edit
    from genr8_dist.errors import ConfigError

    hand = []
    for text in args.hand_fitness or ():
        ident, sep, value = text.partition("=")
        try:
            hand.append((ident.strip(), float(value)))
        except ValueError:
            sep = ""
        if not sep:
            raise ConfigError(f"--hand-fitness {text!r}: expected ID=FITNESS, e.g. 0-12-3=0.25")
    edit = Edit(assignments=args.set or (), inject_copy=args.inject_copy or (),
                inject_text=args.inject_text or (), inject_from=args.inject_from or (),
                island=args.island, generations=args.generations, favour=args.favour or (),
                hand_fitness=hand, trust_hooks=args.trust_hooks)
    result = apply_edit(args.run_dir, edit)
    what = [f"{k} = {v!r}" for k, v in result.changes.items()]
    what += [f"inject {item['source']} into island {item['island']}" for item in result.injected]
    what += [f"hand fitness {h['id']} = {h['fitness']:.6g} (computed {h['computed']:.6g}) among the parents "
             f"of island {h['island']}" for h in result.hand_fitness]
    if result.queued:
        print(f"{args.run_dir}: the run is running; the edit is queued ({result.queued}) and takes effect "
              f"at the first generation the run has not started (generation {result.effective_generation} "
              "or later)")
        for line in what:
            print(f"  {line}")
        return 0
    print(f"{args.run_dir}: configuration version {result.version} in force from generation "
          f"{result.effective_generation} (the run now ends at generation {result.last_generation})")
    for line in what:
        print(f"  {line}")
    if result.set_aside:
        from genr8_dist.store.foreign import describe

        print(describe(result.set_aside, args.run_dir))
    print(f"go on with: genr8 resume {args.run_dir}")
    return 0


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``run``, ``resume``, ``repair`` and ``edit``."""
    p = subparsers.add_parser(
        "run", help="start an evolution run (islands on Ray) in a new run directory",
        description="Start an evolution run of the configuration CONFIG in the new directory DIR, on a "
                    "local Ray or a cluster. Ctrl-C stops it cleanly; `genr8 resume DIR` goes on.")
    p.add_argument("config", metavar="CONFIG", help="the run configuration (TOML; see docs/run-config.md)")
    p.add_argument("--run-dir", required=True, metavar="DIR",
                   help="where the run is kept: a new or empty local directory, or a URI such as s3://b/r")
    _ray_options(p)
    p.add_argument("--studio", action="store_true",
                   help="serve the studio over the run while it runs (and after, until Ctrl-C): watch it "
                        "and steer it from a browser (docs/studio.md)")
    from genr8_dist.cli.studio import add_server_options

    add_server_options(p, prefix="studio-")
    p.set_defaults(handler=_run)

    p = subparsers.add_parser(
        "resume", help="go on with a stopped run from its last committed generation",
        description="Go on with the run in DIR from its last committed generation. A damaged file is "
                    "reported and the run falls back to its last intact generation.")
    p.add_argument("run_dir", metavar="DIR", help="the run directory")
    _ray_options(p)
    p.set_defaults(handler=_resume)

    p = subparsers.add_parser(
        "repair", help="check every file of a run and mend what is damaged, keeping every intact commit",
        description="Check every committed file of the run in DIR against its manifest. A damaged "
                    "configuration is restored from the manifest's copy; a damaged data file is replaced "
                    "by the files it was compacted from, or dropped alone (later commits stay). What is "
                    "dropped is printed in one line and recorded as a recovery event.")
    p.add_argument("run_dir", metavar="DIR", help="the run directory")
    p.add_argument("--upgrade", action="store_true",
                   help="convert a run written before layout 2 in place (one atomic commit), so that any "
                        "Parquet reader reads individuals/*.parquet exactly (docs/run-store.md)")
    p.set_defaults(handler=_repair)

    p = subparsers.add_parser(
        "edit", help="intervene in a run: change its configuration, inject individuals",
        description="Record a new configuration version of the run in DIR, in force from the "
                    "generation after the last committed one, and individuals to inject there. "
                    "Then `genr8 resume DIR`. On a run that is running, the edit is queued and the run "
                    "takes it at the first generation it has not started, without stopping.")
    p.add_argument("run_dir", metavar="DIR", help="the run directory")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="change a configuration value (TOML syntax), e.g. fitness.size.weight=2, "
                        "ea.mutation_rate=0.05, islands.topology=random (repeatable)")
    p.add_argument("--inject-copy", action="append", metavar="ID",
                   help="inject a copy of this run's individual ID (ISLAND-GENERATION-INDEX)")
    p.add_argument("--inject-text", action="append", metavar="FILE",
                   help="inject the rewrite system written in FILE, through the universe's inverse mapping")
    p.add_argument("--inject-from", action="append", metavar="RUN:ID",
                   help="inject individual ID of another run directory RUN")
    p.add_argument("--favour", action="append", metavar="ID",
                   help="favour individual ID as a parent: a copy joins the next generation on its island")
    p.add_argument("--hand-fitness", action="append", metavar="ID=FITNESS",
                   help="give individual ID this fitness (lower is better) when the next generation's "
                        "elites and parents are chosen (interactive evolution; repeatable)")
    p.add_argument("--island", type=int32, default=None, metavar="N",
                   help="the island injected individuals go to (default: a copy's own island, else 0)")
    p.add_argument("--generations", type=int32, default=None, metavar="N",
                   help="go on for N more generations after the last committed one")
    _trust_option(p)
    p.set_defaults(handler=_edit)
