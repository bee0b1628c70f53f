"""``genr8 studio``: watch and steer a run from a browser (docs/studio.md)."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from genr8_dist.studio import Studio

__all__ = ["add_server_options", "register", "start_studio", "wait_for_interrupt"]


def add_server_options(parser: argparse.ArgumentParser, prefix: str = "") -> None:
    """``--host``, ``--port`` and ``--token`` (``--studio-host``... with ``prefix="studio-"``)."""
    parser.add_argument(f"--{prefix}host", default="127.0.0.1", metavar="ADDRESS",
                        help="the address the studio listens on (default 127.0.0.1, this machine only; "
                             "any other address requires the token printed in the URL)")
    parser.add_argument(f"--{prefix}port", type=int, default=8765, metavar="PORT",
                        help="the studio's port (default 8765; 0: any free port)")
    parser.add_argument(f"--{prefix}token", default=None, metavar="TOKEN",
                        help="the token the URL must carry (default: a random one when the address is "
                             "not 127.0.0.1)")


def start_studio(run_dir: str, host: str, port: int, token: str | None) -> Studio:
    """The studio over ``run_dir``, serving in a background thread; prints its URL."""
    from genr8_dist.errors import ConfigError
    from genr8_dist.studio import Studio

    if not 0 <= port <= 65535:
        raise ConfigError(f"--port {port}: must be 0..65535")
    studio = Studio(run_dir, host=host, port=port, token=token).start()
    print(f"studio: {studio.url}", flush=True)
    return studio


def wait_for_interrupt() -> None:
    """Block until Ctrl-C or SIGTERM."""
    done = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: done.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        while not done.wait(0.5):
            pass
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _studio(args: argparse.Namespace) -> int:
    from genr8_dist.store import RunStore

    RunStore.open(args.run_dir)     # a one-line error now if it is not a run
    studio = start_studio(args.run_dir, args.host, args.port, args.token)
    print("Ctrl-C closes the studio", flush=True)
    wait_for_interrupt()
    studio.close()
    print("studio closed", file=sys.stdout, flush=True)
    return 0


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``studio``."""
    p = subparsers.add_parser(
        "studio", help="watch and steer a run from a browser (live while it runs)",
        description="Serve the studio over the run in DIR: progress, fitness and criterion curves, the "
                    "generation's surfaces in 3D, a design's criteria, rewrite system, lineage and "
                    "downloads, and actions (favour, hand-set fitness, weights, environment, inject, "
                    "pause) recorded as genr8 edit records them. See docs/studio.md.")
    p.add_argument("run_dir", metavar="DIR", help="the run directory")
    add_server_options(p)
    p.set_defaults(handler=_studio)
