"""Do two checkouts of genr8_dist write the same rows for the same run? (The optimisations' contract.)

    python bench/same_rows.py /path/to/before /path/to/after
    python bench/same_rows.py BEFORE AFTER --config examples/subdivide.toml --env max_work=0
    python bench/same_rows.py BEFORE AFTER --env branch_join=cone     # a key only one checkout knows

Each checkout runs ``genr8 run CONFIG`` (a local Ray of 2 CPUs, as a user would) in a fresh directory;
then the rows of both runs are compared column by column, all columns but the ``*_seconds`` timings (and
columns only one checkout's store has, which are listed; a checkout from before store schema 3 has its
surface-named digest and sizes compared under their current names). ``--env KEY=VALUE`` adds an
environment field to the configuration of each checkout whose Environment has that field (a checkout
that predates it runs without it), so a cap or an option added later can be switched off or pinned.
Prints the number of rows, how many rows a growth cap touched in each run, the rows that differ (first
few shown) and ``SAME`` or ``DIFFERENT``; exits 1 when they differ.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# Runs in each checkout (its genr8_dist first on the path): write the configuration with the
# environment fields this checkout knows, run it with the CLI, print the rows as JSON lines.
_RUNNER = r"""
import dataclasses, json, subprocess, sys, tomllib
from pathlib import Path
import pyarrow.parquet as pq
from genr8_dist.config import load_config
from genr8_dist.environment import Environment

config_path, extra_json, workdir = sys.argv[1], sys.argv[2], Path(sys.argv[3])
known = {f.name for f in dataclasses.fields(Environment)}
extra = {k: v for k, v in json.loads(extra_json).items() if k in known}
config = load_config(config_path).to_dict()
config.setdefault("environment", {}).update(extra)

def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)

def key(k):   # a bare key, else quoted (a stored universe's file names hold dots)
    return k if k and all(c.isalnum() or c in "_-" for c in k) else json.dumps(k)

def write(table, prefix, out):
    scalars = {k: v for k, v in table.items() if not isinstance(v, dict)}
    tables = {k: v for k, v in table.items() if isinstance(v, dict)}
    if prefix:
        out.append(f"[{prefix}]")
    out.extend(f"{key(k)} = {toml_value(v)}" for k, v in scalars.items())
    for k, v in tables.items():
        write(v, f"{prefix}.{key(k)}" if prefix else key(k), out)

lines = []
write(config, "", lines)
(workdir / "run.toml").write_text("\n".join(lines) + "\n")
run = workdir / "run"
done = subprocess.run([sys.executable, "-m", "genr8_dist.cli", "run", str(workdir / "run.toml"),
                       "--run-dir", str(run), "--cpus", "2", "--quiet"], capture_output=True, text=True)
if done.returncode != 0:
    sys.exit("genr8 run failed: " + (done.stderr.strip().splitlines() or ["?"])[-1])
table = pq.read_table(run / "individuals")
# a checkout from before store schema 3 names the digest and the sizes after surfaces: compare them
# under the current names (genr8_dist.evolution.individual.SCHEMA_2_NAMES)
renamed = {"surface_digest": "phenotype_digest", "n_vertices": "size_vertices", "n_edges": "size_edges",
           "n_regions": "size_regions"}
table = table.rename_columns([renamed.get(n, n) for n in table.column_names])
print(json.dumps({"applied": extra}))
for row in table.to_pylist():
    print(json.dumps(row, default=repr, sort_keys=True))
"""


def rows_of(checkout: Path, config: Path, extra: dict) -> tuple[dict, list[dict]]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(checkout)
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run([sys.executable, "-c", _RUNNER, str(config), json.dumps(extra), tmp],
                             capture_output=True, text=True, env=env, cwd=checkout)
    if out.returncode != 0:
        last = out.stderr.strip().splitlines()[-1] if out.stderr.strip() else "failed"
        raise SystemExit(f"{checkout}: {last}")
    lines = out.stdout.strip().splitlines()
    head = json.loads(lines[0])
    return head["applied"], [json.loads(line) for line in lines[1:]]


def _value(x):
    if isinstance(x, float) and x != x:
        return "nan"
    return x


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--config", type=Path, default=ROOT / "examples" / "quick.toml")
    parser.add_argument("--env", action="append", default=[], metavar="KEY=VALUE",
                        help="an environment field (TOML value) for the checkouts that have it")
    args = parser.parse_args(argv)
    extra = {}
    for item in args.env:
        key, _, value = item.partition("=")
        extra[key.strip()] = tomllib.loads(f"v = {value}")["v"]
    applied_a, a = rows_of(args.before.resolve(), args.config.resolve(), extra)
    applied_b, b = rows_of(args.after.resolve(), args.config.resolve(), extra)
    print(f"config {args.config}; environment additions: before {applied_a or 'none'}, "
          f"after {applied_b or 'none'}")
    key = ("island", "generation", "index")
    a = sorted(a, key=lambda r: tuple(r[k] for k in key))
    b = sorted(b, key=lambda r: tuple(r[k] for k in key))
    cols_a, cols_b = set(a[0]) if a else set(), set(b[0]) if b else set()
    common = sorted(c for c in cols_a & cols_b if not c.endswith("_seconds"))
    only = sorted((cols_a ^ cols_b) - {c for c in cols_a | cols_b if c.endswith("_seconds")})
    print(f"rows: before {len(a)}, after {len(b)}; columns compared {len(common)}"
          + (f"; in one store only (not compared): {', '.join(only)}" if only else ""))
    for name, rows in (("before", a), ("after", b)):
        caps: dict[str, int] = {}
        for r in rows:
            if r.get("capped"):
                caps[r["capped"]] = caps.get(r["capped"], 0) + 1
        print(f"  {name}: rows a growth cap touched: {caps or 'none'}")
    differ = []
    for ra, rb in zip(a, b, strict=False):
        cols = [c for c in common if _value(ra[c]) != _value(rb[c])]
        if cols or tuple(ra[k] for k in key) != tuple(rb[k] for k in key):
            differ.append((tuple(ra[k] for k in key), cols))
    same = not differ and len(a) == len(b)
    for where, cols in differ[:5]:
        print(f"  differs: individual {'-'.join(map(str, where))}: {', '.join(cols)}")
    print(f"{'SAME' if same else 'DIFFERENT'}: {len(differ)} of {max(len(a), len(b))} rows differ")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
