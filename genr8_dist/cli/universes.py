"""``genr8 universes``, ``genr8 map`` and ``genr8 invert``: list universes, map genomes, invert texts.

::

    genr8 universes --json
    genr8 map --universe default --genome 212,187,632,832,800,517,338,39,878,185,954,863
    genr8 map --universe symmetric --random --seed 7 --length 300 --json
    genr8 invert --universe reversible system.hemls          # prints the genome: 0,0,2,...
    genr8 map --universe default --random --seed 1 | genr8 invert --universe default -
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Callable

from genr8_dist.errors import ConfigError, GenomeError, InversionError

__all__ = ["parse_genome", "register"]


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``genr8 universes``, ``genr8 map`` and ``genr8 invert``."""
    p = subparsers.add_parser(
        "universes", help="list the universes (built-in, plugins, entry points) and where each is from",
        description="List every universe discovery finds: the built-ins, the shipped plugins, plugin "
        "folders in GENR8_PLUGINS, and installed packages' 'genr8_dist.universes' entry points; a broken "
        "plugin is listed as BROKEN with its one-line error.")
    p.add_argument("--json", action="store_true", help="print a JSON list")
    p.set_defaults(handler=_universes)

    p = subparsers.add_parser(
        "map", help="map a genome to a rewrite system through a universe",
        description="Map a genome (Genr8's Grammatical Evolution) to a rewrite system and print it. "
        "Exit status 1 when the genome is invalid (it ran out of codons after max-wraps wraps).")
    p.add_argument("--universe", default="default", metavar="NAME",
                   help="a universe name, .lark file or plugin folder (default: default)")
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--genome", metavar="C1,C2,...", help="comma-separated non-negative integers")
    source.add_argument("--random", action="store_true", help="a random genome (see --seed, --length)")
    p.add_argument("--seed", type=int, default=0, metavar="N", help="seed of --random (default 0)")
    p.add_argument("--length", type=int, default=200, metavar="L", help="length of --random (default 200)")
    p.add_argument("--max-codon", type=int, default=65535, metavar="M",
                   help="largest codon of --random (default 65535)")
    p.add_argument("--max-depth", type=int, default=5, metavar="D", help="maximum derivation depth (5)")
    p.add_argument("--max-wraps", type=int, default=2, metavar="W", help="times the genome may wrap (2)")
    p.add_argument("--json", action="store_true",
                   help="print genome, text, valid, reason, codons_used and wraps as JSON")
    p.add_argument("--trust-hooks", action="store_true",
                   help="run the Python code (hooks.py) of a plugin folder given by a path; needed once "
                        "per code digest (the trust rule: docs/run-store.md)")
    p.set_defaults(handler=_map)

    p = subparsers.add_parser(
        "invert", help="turn a rewrite system back into a genome (regn8)",
        description="Find a genome that the universe maps to the given rewrite system (labels renamed "
        "to birth order) and print it as comma-separated integers.")
    p.add_argument("--universe", default="default", metavar="NAME",
                   help="a universe name, .lark file or plugin folder (default: default)")
    p.add_argument("file", metavar="FILE", help="the rewrite system's file, or - for standard input")
    p.add_argument("--max-depth", type=int, default=5, metavar="D", help="maximum derivation depth (5)")
    p.add_argument("--json", action="store_true", help="print universe, genome and text as JSON")
    p.add_argument("--trust-hooks", action="store_true",
                   help="run the Python code (hooks.py) of a plugin folder given by a path; needed once "
                        "per code digest (the trust rule: docs/run-store.md)")
    p.set_defaults(handler=_invert)


def _retry(args: argparse.Namespace) -> str:
    """The command to give again with ``--trust-hooks`` (what the refusal tells the user)."""
    return f"{args.command} --universe {args.universe}"


def parse_genome(text: str) -> list[int]:
    """``"212, 187,632"`` -> ``[212, 187, 632]``; :class:`GenomeError` naming the bad codon."""
    parts = [p.strip() for p in text.replace(";", ",").split(",")]
    if parts and not parts[-1]:
        parts.pop()
    if not parts or parts == [""]:
        raise GenomeError("the genome is empty: give comma-separated non-negative integers")
    genome = []
    for i, part in enumerate(parts):
        try:
            value = int(part, 10)
        except ValueError:
            raise GenomeError(f"codon {i} is {part[:40]!r}: codons are non-negative integers") from None
        if value < 0:
            raise GenomeError(f"codon {i} is {value}: codons are non-negative integers")
        genome.append(value)
    return genome


def _universes(args: argparse.Namespace) -> int:
    from genr8_dist.grammar import list_universes

    infos = list_universes()
    if args.json:
        print(json.dumps([{"name": i.name, "origin": i.origin, "path": str(i.path),
                           "description": i.description, "error": i.error} for i in infos], indent=2))
        return 0
    width = max((len(i.name) for i in infos), default=4)
    owidth = max((len(i.origin) for i in infos), default=6)
    for info in infos:
        about = f"BROKEN: {info.error}" if info.error else info.description or info.path
        print(f"{info.name:<{width}}  {info.origin:<{owidth}}  {about}")
    return 0


def _map(args: argparse.Namespace) -> int:
    from genr8_dist.grammar.discovery import load_named_universe

    for name, value, low in (("--max-depth", args.max_depth, 1), ("--max-wraps", args.max_wraps, 0),
                             ("--length", args.length, 1), ("--max-codon", args.max_codon, 0),
                             ("--seed", args.seed, 0)):
        if value < low:
            raise ConfigError(f"{name} must be >= {low}, got {value}")
    if args.max_depth > 100:
        raise ConfigError(f"--max-depth must be <= 100, got {args.max_depth}")
    for name, value, high in (("--max-wraps", args.max_wraps, 1000), ("--length", args.length, 1_000_000)):
        if value > high:
            raise ConfigError(f"{name} must be <= {high}, got {value}")
    if args.max_codon > 2**31 - 1:
        raise ConfigError(f"--max-codon must be <= {2**31 - 1} (codons are 32-bit), got {args.max_codon}")
    universe = load_named_universe(args.universe, trust_flag=args.trust_hooks, command=_retry(args))
    if args.random:
        from genr8_dist.rng import stream

        rng = stream(args.seed, "cli", "map")
        genome = rng.integers(0, args.max_codon + 1, size=args.length).tolist()
    else:
        genome = parse_genome(args.genome)
    result = universe.map(genome, max_depth=args.max_depth, max_wraps=args.max_wraps)
    warnings: list[str] = []
    from genr8_dist.phenotype import SURFACES, phenotype_of

    if result.valid and phenotype_of(universe) is SURFACES:  # another phenotype reads its own texts
        from genr8_dist.errors import ParseError
        from genr8_dist.hemls import parse

        try:
            warnings = parse(result.text or "", source="mapped").warnings()
        except ParseError as exc:  # a universe whose texts the HEMLS parser does not take
            warnings = [f"the rewrite system does not parse: {exc}"]
    if args.json:
        print(json.dumps({"universe": universe.name, "genome": genome, "text": result.text,
                          "valid": result.valid, "reason": result.reason,
                          "codons_used": result.codons_used, "wraps": result.wraps,
                          "warnings": warnings}))
        return 0 if result.valid else 1
    if not result.valid:
        print(f"genr8: invalid genome: {result.reason}", file=sys.stderr)
        return 1
    for warning in warnings:
        print(f"genr8: warning: {warning}", file=sys.stderr)
    sys.stdout.write(result.text or "")
    return 0


def _invert(args: argparse.Namespace) -> int:
    from genr8_dist.grammar.discovery import load_named_universe

    if not 1 <= args.max_depth <= 100:
        raise ConfigError(f"--max-depth must be from 1 to 100, got {args.max_depth}")
    universe = load_named_universe(args.universe, trust_flag=args.trust_hooks, command=_retry(args))
    try:
        if args.file == "-":
            text = sys.stdin.read()
        else:
            with open(args.file, encoding="utf-8") as handle:
                text = handle.read()
    except UnicodeDecodeError as exc:
        raise InversionError(f"{args.file}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    source = "<stdin>" if args.file == "-" else args.file
    kept, original_line = _without_comments(text)
    try:
        genome = universe.invert(kept, max_depth=args.max_depth)
    except InversionError as exc:
        message = re.sub(r"^line (\d+)", lambda m: f"line {original_line(int(m.group(1)))}", str(exc))
        raise InversionError(f"{source}: {message}") from None
    if args.json:
        mapped = universe.map(genome, max_depth=args.max_depth)
        print(json.dumps({"universe": universe.name, "genome": list(genome), "text": mapped.text}))
    else:
        print(",".join(map(str, genome)))
    return 0


def _without_comments(text: str) -> tuple[str, Callable[[int], int]]:
    """``text`` without its comment lines (``//`` or ``#``) and blank lines, which no universe derives,
    and a function from a line number of the result to the line number in ``text``."""
    kept: list[str] = []
    numbers: list[int] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith(("//", "#")):
            continue
        kept.append(line)
        numbers.append(number)
    return "\n".join(kept) + "\n", lambda n: numbers[n - 1] if 0 < n <= len(numbers) else n
