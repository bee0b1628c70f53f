"""``genr8 score``: grow one rewrite system and print every criterion and the total fitness.

The way to check what a fitness specification rewards before a long run::

    genr8 score four-sided-tiles
    genr8 score my-system.hemls --env env.toml --fitness examples/quick.toml
    echo "Edge0 + Edge0 + Edge0 ..." | genr8 score - --json
    genr8 score table.txt --fitness examples/tables.toml    # a plugin phenotype's text (tables)
"""

from __future__ import annotations

import argparse
import json
import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.environment import Environment
    from genr8_dist.fitness import FitnessSpec
    from genr8_dist.hemls import RewriteSystem

__all__ = ["register", "score_phenotype", "score_system"]


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``genr8 score``."""
    parser = subparsers.add_parser(
        "score",
        help="grow one rewrite system and print every fitness criterion and the total",
        description="Grow one rewrite system in an environment and print, for every criterion, the raw "
        "value, the target, the weight and the weighted deviation, then the total fitness (lower is "
        "better). Use it to check what a fitness specification rewards before a long run.",
    )
    parser.add_argument("system", metavar="SYSTEM",
                        help="a rewrite-system file, the name of a predefined system (e.g. "
                        "four-sided-tiles, square, koch), or - to read standard input")
    parser.add_argument("--env", metavar="ENV.toml", help="the environment to grow in (default: the "
                        "--fitness configuration's environment, else the default environment)")
    parser.add_argument("--fitness", metavar="CONFIG.toml", help="a run configuration whose [fitness] "
                        "targets and weights to use (default: the built-in defaults)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.set_defaults(handler=_handle)


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def score_system(system: RewriteSystem | str, env: Environment, spec: FitnessSpec, *,
                 name: str = "<text>") -> dict[str, Any]:
    """Grow ``system`` (a ``RewriteSystem``, or its text) in ``env`` and score it under ``spec``: the
    report ``genr8 score`` prints (JSON-ready). Text that does not parse raises ``ParseError``; growth
    that cannot start raises ``GrowthError``."""
    from genr8_dist.config import RunConfig
    from genr8_dist.errors import GrowthError
    from genr8_dist.evolution.evaluate import evaluate_text
    from genr8_dist.hemls import parse

    if isinstance(system, str):
        system = parse(system, source=name)
    text = system.to_text() if hasattr(system, "to_text") else str(system)
    judged = evaluate_text(text, RunConfig(fitness=spec, environment=env))  # as a run evaluates it
    if not judged.criteria:
        raise GrowthError(f"{name}: {judged.error}")
    raw = judged.criteria
    deviations = spec.deviations(raw)
    total = spec.evaluate(raw)
    return {
        "system": name,
        "text": text,
        **{name: judged.sizes.get(name, 0) for name in ("vertices", "edges", "regions")},
        "steps": judged.steps_done,
        "capped": judged.capped,
        "criteria": {key: {"raw": _finite(raw[key]), "target": spec[key].target,
                           "weight": spec[key].weight, "deviation": _finite(deviations[key])}
                     for key in spec.names},
        "total": _finite(total),
        "valid": judged.valid,
        "problem": judged.error,
    }


def _fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.6g}"


def _print_table(report: dict[str, Any], mentioned: set[str] | None = None) -> None:
    """The report as a table; with ``mentioned`` (the criteria a ``--fitness`` configuration names), a
    criterion it does not name and that counts for nothing (weight 0, the default) is left out, and
    one it does not name that counts by default is marked ``(default)``."""
    def count(n: int, noun: str) -> str:
        return f"{n} {noun}" if n == 1 else f"{n} {noun}s"

    print(f"{report['system']}: {report['vertices']} vertices, {count(report['edges'], 'edge')}, "
          f"{count(report['regions'], 'region')} after {count(report['steps'], 'derivation step')}")
    header = f"{'criterion':<14} {'raw':>12} {'target':>10} {'weight':>8} {'deviation':>12}"
    print(header)
    print("-" * len(header))
    for name, row in report["criteria"].items():
        default = mentioned is not None and name not in mentioned
        if default and not row["weight"]:
            continue
        print(f"{name:<14} {_fmt(row['raw']):>12} {_fmt(row['target']):>10} {_fmt(row['weight']):>8} "
              f"{_fmt(row['deviation']):>12}" + ("   (default)" if default else ""))
    print("-" * len(header))
    print(f"{'total':<14} {'':>12} {'':>10} {'':>8} {_fmt(report['total']):>12}   (lower is better)")
    if report["problem"]:
        print(f"note: in a run this individual is invalid (fitness inf): {report['problem']}")


def score_phenotype(text: str, config: RunConfig, *, name: str = "<text>") -> dict[str, Any]:
    """Develop ``text`` with the phenotype of ``config``'s universe (a plugin's, e.g. tables) and
    score it as a run would: the report ``genr8 score`` prints for such a universe (JSON-ready)."""
    from genr8_dist.evolution.evaluate import evaluate_text

    ev = evaluate_text(text, config)
    return {"system": name, "universe": config.universe, "text": text, "steps": ev.steps_done,
            "capped": ev.capped, "criteria": {k: _finite(v) for k, v in ev.criteria.items()},
            "fitness": _finite(ev.fitness), "valid": ev.valid,
            "problem": None if ev.valid else f"{ev.stage}: {ev.error}"}


def _print_phenotype(report: dict[str, Any]) -> None:
    print(f"{report['system']} (universe {report['universe']}): {report['steps']} derivation steps"
          + (f", capped ({report['capped']})" if report["capped"] else ""))
    for name, value in report["criteria"].items():
        print(f"{name:<14} {_fmt(value):>12}")
    print(f"{'fitness':<14} {_fmt(report['fitness']):>12}   (lower is better)")
    if report["problem"]:
        print(f"note: in a run this individual is invalid (fitness inf): {report['problem']}")


def _handle(args: argparse.Namespace) -> int:
    from pathlib import Path

    from genr8_dist.config import load_config
    from genr8_dist.environment import Environment, load_environment
    from genr8_dist.errors import Genr8Error
    from genr8_dist.evolution.evaluate import universe_for
    from genr8_dist.fitness import FitnessSpec
    from genr8_dist.hemls import load_system
    from genr8_dist.phenotype import SURFACES, phenotype_of

    spec, env = FitnessSpec(), None
    mentioned: set[str] | None = None
    if args.fitness:
        config = load_config(args.fitness)
        mentioned = _mentioned(args.fitness)
        spec, env = config.fitness, config.environment
        if phenotype_of(universe_for(config)) is not SURFACES:
            name = "<stdin>" if args.system == "-" else args.system
            try:
                import sys

                text = sys.stdin.read() if args.system == "-" else Path(args.system).read_text("utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                raise Genr8Error(f"{args.system}: cannot read the text: {exc}") from None
            report = score_phenotype(text, config, name=name)
            if args.json:
                print(json.dumps(report, indent=2))
            else:
                _print_phenotype(report)
            return 0
    if args.env:
        env = load_environment(args.env)
    if env is None:
        env = Environment()
    system = load_system(args.system)
    name = "<stdin>" if args.system == "-" else args.system
    report = score_system(system, env, spec, name=name)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        _print_table(report, mentioned)
    return 0


def _mentioned(path: str) -> set[str]:
    """The criteria the ``[fitness]`` table of the configuration file at ``path`` names."""
    from genr8_dist.tomlfile import read_toml

    table = read_toml(path, "run configuration").get("fitness")
    return set(table) if isinstance(table, dict) else set()
