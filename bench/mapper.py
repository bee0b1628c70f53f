"""Benchmark the GE mapper: genomes mapped per CPU second, per universe, on one core.

Genomes have 200 codons drawn uniformly from 0..65535 (the issue's setting). Times are the process's
CPU time (``time.process_time``), so other work on a shared machine does not count. For scale on the
machine at hand it also times a PonyGE2-style mapper (the algorithm of PonyGE2's
``map_ind_from_genome``: a list of unexpanded symbols, one codon per choice) over a plain-BNF
approximation of the default universe without Genr8's rules (no labels, depth control, binding or
repair), which PonyGE2 maps at about 19,000 genomes/s on a typical core.

    python bench/mapper.py                 # every universe, 20,000 genomes for default
    python bench/mapper.py --n 5000 --universe default --universe symmetric
"""

from __future__ import annotations

import argparse
import statistics
import time

from genr8_dist.grammar import list_universes, load_universe
from genr8_dist.rng import stream

# A plain BNF approximation of the default universe (journal Fig. 6) for the PonyGE2-style mapper.
_BNF = {
    "ls": [["axiom", "\n", "rules", "Angle", "av", "\n", "sync", "BranchAngle", "bav", "\n"]],
    "axiom": [["e", "+", "e", "+", "e", "axmore"]],
    "axmore": [[], ["+", "e", "axmore"]],
    "rules": [["rule", "\n"], ["rule", "\n", "rules"]],
    "rule": [["pred", "->", "succ"]],
    "pred": [["e"], ["e", "<", "e"], ["e", ">", "e"], ["e", "<", "e", ">", "e"]],
    "succ": [["mods", "e"]],
    "mods": [[], ["mod", "mods"]],
    "mod": [["edges"], ["+", "mod", "-"], ["-", "mod", "+"], ["&", "mod", "^"], ["^", "mod", "&"],
            ["\\", "mod", "/"], ["/", "mod", "\\"], ["~", "mod"],
            ["e", "[", "[", "+", "e", "]", "-", "e", "]", "e"],
            ["e", "[", "[", "+", "+", "e", "]", "-", "-", "e", "]", "e"]],
    "edges": [[], ["e", "edges"]],
    "e": [["Edge0"], ["Edge1"], ["Edge2"], ["Edge3"]],
    "av": [["30"], ["45"]],
    "sync": [[], ["Sync", "\n"]],
    "bav": [["15"], ["30"], ["45"], ["60"], ["75"]],
}


def _ponyge_grammar() -> dict:
    rules = {}
    for name, choices in _BNF.items():
        rules[name] = {"choices": [{"choice": [{"symbol": s, "type": "NT" if s in _BNF else "T"}
                                              for s in choice]} for choice in choices],
                       "no_choices": len(choices)}
    return {"rules": rules, "start_rule": {"symbol": "ls", "type": "NT"}}


def ponyge_map(genome: list[int], bnf: dict, max_wraps: int = 2, max_tree_depth: int = 90):
    """PonyGE2's ``map_ind_from_genome`` (linear genome, one codon per choice), reproduced."""
    n_input = len(genome)
    used_input, current_depth, max_depth, nodes, wraps = 0, 0, 0, 1, -1
    output: list[str] = []
    unexpanded_symbols = [(bnf["start_rule"], 0)]
    while (wraps < max_wraps) and unexpanded_symbols:
        if used_input % n_input == 0 and used_input > 0 and \
                any(i[0]["type"] == "NT" for i in unexpanded_symbols):
            wraps += 1
        nodes += 1
        current_item = unexpanded_symbols.pop(0)
        current_symbol, current_depth = current_item[0], current_item[1]
        if max_depth < current_depth:
            max_depth = current_depth
        if current_symbol["type"] == "T":
            output.append(current_symbol["symbol"])
        else:
            production_choices = bnf["rules"][current_symbol["symbol"]]["choices"]
            no_choices = bnf["rules"][current_symbol["symbol"]]["no_choices"]
            chosen_prod = production_choices[genome[used_input % n_input] % no_choices]
            used_input += 1
            children = [(prod, current_depth + 1) for prod in chosen_prod["choice"]]
            unexpanded_symbols = children + unexpanded_symbols
    invalid = bool(unexpanded_symbols) or max_depth > max_tree_depth
    return None if invalid else " ".join(output), used_input


def _genomes(name: str, n: int, length: int, seed: int) -> list[list[int]]:
    return stream(seed, "bench", "mapper", name).integers(0, 65536, size=(n, length)).tolist()


def _best_rate(fn, genomes, repeats: int) -> tuple[float, list]:
    best, results = 0.0, []
    for _ in range(repeats):
        start = time.process_time()
        results = [fn(g) for g in genomes]
        elapsed = time.process_time() - start
        best = max(best, len(genomes) / elapsed)
    return best, results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20_000, help="genomes for default (others: n/4)")
    parser.add_argument("--length", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3, help="best of this many passes")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--universe", action="append", help="only these (default: all found)")
    args = parser.parse_args()

    start = time.process_time()
    x = 0
    for i in range(5_000_000):
        x += i
    loop = time.process_time() - start
    print(f"machine: a 5M-iteration Python loop takes {loop:.2f} CPU s here "
          "(about 0.2-0.3 s on a recent desktop core)")
    print(f"genome length {args.length}, codons 0..65535, max_depth 5, max_wraps 2, one core, "
          f"best of {args.repeats}")
    print(f"{'universe':<14} {'genomes/s':>10} {'codons used':>12} {'valid':>7} {'wrapped':>8}")
    names = args.universe or [info.name for info in list_universes()]
    for name in names:
        u = load_universe(name)
        n = args.n if name == "default" else max(1, args.n // 4)
        genomes = _genomes(name, n, args.length, args.seed)
        u.map(genomes[0])  # compile outside the timing
        rate, results = _best_rate(u.map, genomes, args.repeats)
        codons = statistics.fmean(r.codons_used for r in results)
        valid = sum(r.valid for r in results) / len(results)
        wrapped = sum(r.wraps > 0 for r in results) / len(results)
        print(f"{name:<14} {rate:>10,.0f} {codons:>12.1f} {valid:>7.1%} {wrapped:>8.1%}")
    bnf = _ponyge_grammar()
    genomes = _genomes("ponyge", max(1, args.n // 4), args.length, args.seed)
    rate, results = _best_rate(lambda g: ponyge_map(g, bnf), genomes, args.repeats)
    codons = statistics.fmean(used for _, used in results)
    valid = sum(text is not None for text, _ in results) / len(results)
    print(f"{'ponyge2-style':<14} {rate:>10,.0f} {codons:>12.1f} {valid:>7.1%} {'':>8}"
          "   (plain BNF, no Genr8 rules: for scale)")


if __name__ == "__main__":
    main()
