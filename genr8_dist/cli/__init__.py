"""The ``genr8`` command: a thin dispatcher over one module per group of subcommands.

Each module in ``COMMAND_MODULES`` defines ``register(subparsers)``, adding its subcommands with a
``handler(args) -> int`` default. Modules import heavy packages (ray, pyarrow, trimesh) inside their
handlers so that ``genr8 --help`` answers at once. Errors a user caused are ``Genr8Error`` (or an
``OSError`` on a named file): they print as one line and exit with status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from genr8_dist import __version__
from genr8_dist.errors import Genr8Error

__all__ = ["build_parser", "main"]

# Subcommand modules, in the order their commands are listed by --help.
COMMAND_MODULES: tuple[str, ...] = ("universes", "grow", "score", "run", "history", "studio")


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser, every subcommand registered."""
    parser = argparse.ArgumentParser(
        prog="genr8",
        description="Grow surfaces from map L-systems and evolve them with Grammatical Evolution.",
    )
    parser.add_argument("--version", action="version", version=f"genr8 {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(f"genr8_dist.cli.{name}").register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``genr8`` with ``argv`` (default: the process arguments); returns the exit status. Without
    ``argv`` this is the process's own command, which exits when it returns (``args.exits``: a run's
    command then leaves SIGINT and SIGTERM ignored once its run returns); called with ``argv`` (in
    a test, say) it leaves the process's signal handlers as they were."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.exits = argv is None
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help()
        return 2
    try:
        return int(handler(args) or 0)
    except Genr8Error as exc:
        print(f"genr8: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0
    except OSError as exc:
        # name the file: from the exception, else from its message (pyarrow's errors carry the path
        # only there), never a bare "No such file or directory"
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        text = (exc.strerror or str(exc)) if where else (str(exc).strip() or exc.strerror or repr(exc))
        print(f"genr8: error: {where}{text.splitlines()[0]}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("genr8: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
