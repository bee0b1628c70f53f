"""Benchmark compiling a universe whose rules form a chain, each using the next twice
(``rI: rJ "+" | "-" rJ``): inlining every rule where it is used would copy the last one 2^n times
(issue 17: 16 rules took 10 s and 1.2 GB, 18 a MemoryError, 30 more than 600 s). Prints, per chain
length, the seconds to compile the grammar (``compile_grammar``) and to build the mapper at
``max_depth`` 40 (or the chain's depth, if deeper), the generated source's lines and the process's peak
memory.

    python bench/universe_compile.py                  # 16, 18, 30, 100 and 400 rules
    python bench/universe_compile.py --rules 30 --rules 60
"""

from __future__ import annotations

import argparse
import resource
import time
from pathlib import Path


def chained(n: int) -> str:
    lines = ['start: EDGE "+" EDGE "+" EDGE "\\n" EDGE "->" r0 "\\n"', "EDGE: /Edge[0-9]+/"]
    for i in range(n):
        nxt = f"r{i + 1}" if i + 1 < n else "EDGE"
        lines.append(f'r{i}: {nxt} "+" | "-" {nxt}')
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rules", type=int, action="append", help="chain lengths (repeatable)")
    args = parser.parse_args()
    from genr8_dist.grammar.compiler import MAX_MAX_DEPTH, compile_grammar
    from genr8_dist.grammar.mapper import build_source
    from genr8_dist.grammar.universe import Universe

    print(f"{'rules':>6} {'compile s':>10} {'mapper s':>9} {'source lines':>13} {'peak MB':>8}")
    for n in args.rules or [16, 18, 30, 100, 400]:
        text = chained(n)
        t0 = time.perf_counter()
        grammar = compile_grammar(text, f"chain{n}.lark")
        t1 = time.perf_counter()
        depth = min(MAX_MAX_DEPTH, max(40, grammar.min_depth["start"]))
        universe = Universe(f"chain{n}", "path", Path(f"chain{n}.lark"), text)
        t2 = time.perf_counter()
        universe.mapper(depth)
        t3 = time.perf_counter()
        lines = build_source(grammar, depth).count("\n")
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"{n:>6} {t1 - t0:>10.2f} {t3 - t2:>9.2f} {lines:>13,} {peak:>8.0f}")


if __name__ == "__main__":
    main()
