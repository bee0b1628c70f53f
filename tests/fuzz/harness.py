"""A seeded fuzz harness for the ``genr8`` command: mutated shipped files and mutated arguments.

Every input is drawn from ``rng.stream(seed, "fuzz", n)`` alone, so input ``n`` is the same in every
process (``--case N`` or ``GENR8_FUZZ_CASE=N`` replays it; a file of the fixture run is picked by its
name without the store's random writer token). An input is a command (``grow``, ``score``, ``map``,
``invert``, ``run``, the history commands, ``edit``, ``repair``) with arguments pulled towards the
edges (negative, zero, huge, not a number, empty), and, for the commands that read a file, a shipped
file of each kind a user gives (``KINDS``: universes ``.lark``, HEMLS rewrite systems, environment
TOML, run TOML, genomes; and the fixture run's stored files) mutated (bits flipped, cut short, binary
junk, a number made extreme, a line repeated, brackets nested 5,000 deep). Each input runs
``genr8_dist.cli.main`` in a worker process (memory capped, so a runaway allocation shows as a
failure instead of swapping the machine) and is judged:

* **traceback**: an exception escaped ``main`` (or the worker died);
* **hang**: it ran over ``HANG_SECONDS`` of CPU time (or ``HANG_WALL`` of wall time);
* **silent failure**: a non-zero exit status with nothing on stderr;
* **run changed by a reader**: a history command changed a byte of the run it read;
* **store damaged by a writer**: after ``edit`` or ``repair``, ``verify()`` finds a problem.

A ``run`` whose input passes every check reaches the point where Ray starts: that is accepted (it
would then run for as long as it asks) and is stopped there, never mistaken for a hang.

``python -m tests.fuzz.harness --inputs 1000 --seed 1`` prints the counts and each failing input;
``tests/fuzz/test_fuzz.py`` runs it (marked slow).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
HANG_SECONDS = 30       # CPU seconds of the worker: the machine's load from other work does not count
HANG_WALL = 180         # wall-clock seconds, for an input that waits without computing
MEMORY_LIMIT = 4 << 30  # bytes of address space a worker may use (numba's compiled kernels map ~0.5 GiB)
READERS = ("history", "top", "lineage", "show", "query", "gallery", "report")
EDGES = ["-1", "0", "1", "2147483648", str(2**70), "-" + str(2**70), "1e309", "nan", "inf", "", "abc",
         "-0", "999999999", "0x10", "1_000", " 3", "\x00", "é"]
IDS = ["0-0-0", "1-3-2", "9-9-9", "x", "-1-0-0", "0-0-99999999999999999999", "0--0", "", "0-1-0-0"]
SQL = ["select count(*) from individuals", "select * from events", "select * from configs",
       "select generation, min(fitness) from individuals group by 1 order by 1",
       "select * from read_csv('/etc/passwd')", "copy (select 1) to '/tmp/genr8-fuzz-escape.csv'",
       "select", ";", "select 1/0", "select * from individuals where text like '%[%'",
       "with recursive r(n) as (select 1 union all select n+1 from r where n < 100000) "
       "select count(*) from r",
       "select repeat('x', 1000000)", "pragma version", "select unnest(genome) from individuals limit 5"]
SETS = ["ea=1", "ea.generations=-1", "ea.generations=5", "ea.mutation_rate=0.02", "ea.mutation_rate=nan",
        "fitness.size.weight=2", "fitness.size=1", "islands.count=0", "islands.count=3", "universe=\"x\"",
        "seed=" + str(2**70), "genome.length=0", "environment.steps=1000000", "ea.population=0",
        "nothing.here=1", "=", "ea.generations", "ea.generations=\"ten\"", "fitness.size.target=inf"]


@dataclass
class Outcome:
    """How one input ended."""

    n: int
    argv: list[str]
    kind: str              # ok, error, traceback, hang, silent, reader-wrote, store-damaged
    rc: int | None = None
    detail: str = ""
    seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


# --- drawing inputs ------------------------------------------------------------------------------

#: Every kind of file a user gives genr8, and where the shipped ones are (stored run files are the
#: fixture run's, mutated by the ``repair`` family).
KINDS = ("universe", "system", "env", "config", "genome")


def _shipped(kind: str) -> list[Path]:
    if kind == "universe":
        return sorted(p for p in (ROOT / "grammars").glob("*.lark") if p.name != "hemls.lark")
    if kind == "system":
        return sorted((ROOT / "grammars" / "systems").glob("*.hemls"))
    if kind == "env":
        return sorted((ROOT / "examples" / "environments").glob("*.toml"))
    if kind == "genome":
        return [ROOT / "tests" / "fuzz" / "genome.txt"]
    return sorted((ROOT / "examples").glob("*.toml"))


def _stable(path: Path, root: Path) -> str:
    """``path`` relative to ``root`` without the store's random writer token, so that a file is picked
    by the same number in every build of the fixture run (the tokens differ between builds)."""
    import re

    return re.sub(r"-[0-9a-f]{16}(?=\.)", "", str(path.relative_to(root)))


def mutate(data: bytes, rng: Any) -> bytes:
    """One seeded mutation of ``data``."""
    how = int(rng.integers(0, 9))
    if how == 0 and data:                                   # flip 1-8 bits
        out = bytearray(data)
        for _ in range(int(rng.integers(1, 9))):
            k = int(rng.integers(0, len(out)))
            out[k] ^= 1 << int(rng.integers(0, 8))
        return bytes(out)
    if how == 1:                                            # cut short
        return data[: int(rng.integers(0, len(data) + 1))]
    if how == 2:                                            # binary junk inserted
        k = int(rng.integers(0, len(data) + 1))
        return data[:k] + bytes(rng.integers(0, 256, int(rng.integers(1, 64))).tolist()) + data[k:]
    if how == 3:                                            # a number made extreme
        text = data.decode("utf-8", "replace")
        import re

        numbers = list(re.finditer(r"-?\d+(\.\d+)?", text))
        if numbers:
            m = numbers[int(rng.integers(0, len(numbers)))]
            value = EDGES[int(rng.integers(0, 9))] or "0"
            return (text[: m.start()] + value + text[m.end():]).encode()
        return data
    if how == 4:                                            # a line repeated many times
        lines = data.splitlines(keepends=True) or [b"\n"]
        k = int(rng.integers(0, len(lines)))
        return b"".join(lines[:k] + [lines[k]] * int(rng.integers(2, 400)) + lines[k:])
    if how == 5:                                            # brackets nested deep
        depth = int(rng.choice([50, 500, 5000]))
        return data + b"\na -> a " + b"[" * depth + b"b" + b"]" * depth + b"\n"
    if how == 6:
        return b""
    if how == 7:                                            # pure noise
        return bytes(rng.integers(0, 256, int(rng.integers(1, 2000))).tolist())
    return data.replace(b"=", b"= [", 1)                    # a structural break


def draw(n: int, seed: int, work: Path, run: Path) -> list[str]:
    """The arguments of input ``n`` (files it needs are written under ``work``)."""
    from genr8_dist.rng import stream

    rng = stream(seed, "fuzz", n)

    def pick(items: list[Any]) -> Any:
        return items[int(rng.integers(0, len(items)))]

    def edge() -> str:
        return pick(EDGES)

    def mutated(kind: str) -> str:
        source = pick(_shipped(kind))
        target = work / f"in-{n}{source.suffix}"
        target.write_bytes(mutate(source.read_bytes(), rng))
        return str(target)

    family = pick(["grow", "grow", "score", "map", "invert", "run", "reader", "reader", "reader",
                   "edit", "repair", "args", "universe", "genome"])
    if family == "universe":
        universe = mutated("universe")
        return pick([["map", "--universe", universe, "--random", "--seed", str(n)],
                     ["invert", "--universe", universe, str(ROOT / "grammars" / "systems" / "square.hemls")],
                     ["map", "--universe", universe, "--genome", "1,2,3,4,5,6,7,8,9"]])
    if family == "genome":
        genome = Path(mutated("genome")).read_bytes().decode("utf-8", "replace").replace("\x00", "")
        return ["map", "--genome", genome, *pick([[], ["--universe", "reversible"], ["--json"]])]
    if family == "grow":
        argv = ["grow", mutated("system") if rng.random() < 0.6 else pick(["three-sided", "koch", "x"])]
        if rng.random() < 0.5:
            argv += ["--env", mutated("env")]
        if rng.random() < 0.4:
            argv += ["--steps", pick(["3", "0", "-1", "12", "100000", edge()])]
        if rng.random() < 0.2:
            argv += ["--seed", edge()]
        return argv
    if family == "score":
        argv = ["score", mutated("system") if rng.random() < 0.5 else "three-sided"]
        if rng.random() < 0.5:
            argv += ["--env", mutated("env")]
        if rng.random() < 0.4:
            argv += ["--fitness", mutated("config")]
        return argv
    if family == "map":
        argv = ["map", "--random"] if rng.random() < 0.7 else ["map", "--genome", pick(
            ["1,2,3", "1,,2", "-1", "a", "", str(2**70), ",".join(["7"] * 5000)])]
        for flag in ("--seed", "--length", "--max-codon", "--max-depth", "--max-wraps"):
            if rng.random() < 0.3:
                argv += [flag, edge()]
        return argv
    if family == "invert":
        return ["invert", mutated("system")] + (["--max-depth", edge()] if rng.random() < 0.3 else [])
    if family == "run":
        return ["run", mutated("config"), "--run-dir", str(work / f"run-{n}")]
    if family == "edit":
        copy = work / f"edit-{n}"
        shutil.copytree(run, copy)
        argv = ["edit", str(copy)]
        for _ in range(int(rng.integers(0, 3))):
            argv += ["--set", pick(SETS)]
        if rng.random() < 0.4:
            argv += ["--generations", pick(["3", "0", "-1", edge()])]
        if rng.random() < 0.3:
            argv += ["--inject-copy", pick(IDS)]
        if rng.random() < 0.2:
            argv += ["--inject-text", mutated("system")]
        if rng.random() < 0.15:
            argv += ["--island", edge()]
        return argv
    if family == "repair":
        copy = work / f"repair-{n}"
        shutil.copytree(run, copy)
        files = sorted((p for p in copy.rglob("*") if p.is_file() and p.name != "_running.lock"),
                       key=lambda p: _stable(p, copy))
        victim = pick(files)
        victim.write_bytes(mutate(victim.read_bytes(), rng))
        command = pick(["repair", "repair", "history", "top", "query"])
        return [command, str(copy)] + (["select count(*) from individuals"] if command == "query" else [])
    if family == "args":
        base = pick([["history", str(run)], ["top", str(run)], ["map", "--random"], ["grow", "koch"]])
        for _ in range(int(rng.integers(1, 4))):
            base.insert(int(rng.integers(1, len(base) + 1)), pick(["--x", "-k", "--island", edge(), "--",
                                                                   "-", "--json", "--png"]))
        return base
    command = pick(list(READERS))
    argv = [command, str(run)]
    if command == "history":
        argv += pick([[], ["--island", edge()], ["--png", str(work / f"c-{n}.png")],
                      ["--csv", str(run / "h.csv")]])
    elif command == "top":
        argv += pick([[], ["-k", edge()], ["--generation", edge()], ["--island", edge()],
                      ["--criterion", pick(["size", "x", ""])], ["--systems"]])
    elif command == "lineage":
        argv += [pick(IDS), *pick([[], ["--depth", edge()], ["--all"]])]
    elif command == "show":
        argv += [pick(IDS), *pick([[], ["--grammar", str(work / f"g-{n}.txt")],
                                   ["-o", str(work / f"s-{n}.obj")], ["-o", str(work / f"s-{n}.xyz")],
                                   ["-o", str(run / "inside.obj")]])]
    elif command == "query":
        argv += [pick(SQL), *pick([[], ["--max-rows", edge()], ["--timeout", pick(["0.5", "0", "-1", "x"])],
                                   ["--csv", str(work / f"q-{n}.csv")]])]
    elif command == "gallery":
        argv += ["-o", str(work / f"g-{n}.png"), "-k", pick(["1", "2", "0", "-3", "100000"]),
                 *pick([[], ["--generation", edge()], ["--per-island"]])]
    else:
        argv += ["-o", str(work / f"r-{n}.html"), "-k", pick(["1", "0", "-1", "3"]),
                 "--gallery", pick(["1", "0", "2"])]
    return argv


# --- running one input -----------------------------------------------------------------------------

class _Hang(BaseException):
    pass


def _tree(path: Path) -> str:
    digest = hashlib.sha256()
    for p in sorted(path.rglob("*")):
        if p.is_file() and p.name != "_running.lock":
            digest.update(str(p.relative_to(path)).encode() + b"\0" + p.read_bytes())
    return digest.hexdigest()


class _Started(BaseException):
    """``genr8 run`` reached Ray: every check of its input passed, and the evolution would start."""


def _run_until_it_starts(n: int, argv: list[str]) -> Outcome | None:
    """``genr8 run`` up to the moment it would start Ray, which counts as accepted (a valid
    configuration runs for as long as it asks, which is no hang); None when it was refused, so that
    ``run_one`` runs it again to judge the refusal."""
    from genr8_dist.cli import main
    from genr8_dist.distributed import session

    @contextlib.contextmanager
    def started(*args: Any, **kwargs: Any) -> Any:
        raise _Started()
        yield  # pragma: no cover

    real = session.connect_ray
    session.connect_ray = started  # type: ignore[assignment]
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            main(argv)
    except _Started:
        return Outcome(n, argv, "ok", 0, "accepted: the run starts")
    except BaseException:   # judged again, with its output, by run_one
        pass
    finally:
        session.connect_ray = real
    return None


def _answered(argv: list[str], rc: int | None, out: str) -> bool:
    """A non-zero exit that is the command's documented answer: ``map --json`` of an invalid genome
    (exit 1, the JSON says ``"valid": false`` and why)."""
    if argv[:1] != ["map"] or "--json" not in argv or rc != 1:
        return False
    try:
        answer = json.loads(out)
    except json.JSONDecodeError:
        return False
    return isinstance(answer, dict) and answer.get("valid") is False and bool(answer.get("reason"))


def run_one(n: int, argv: list[str], run: Path) -> Outcome:
    """Run ``genr8 argv`` in this process and judge how it ended."""
    from genr8_dist.cli import main

    reader = argv[0] in READERS and argv[1:2] == [str(run)]
    if argv[0] == "run":
        outcome = _run_until_it_starts(n, argv)
        if outcome is not None:
            return outcome
    before = _tree(run) if reader else ""
    out, err = io.StringIO(), io.StringIO()

    def alarm(signum: int, frame: Any) -> None:
        raise _Hang()

    old = signal.signal(signal.SIGALRM, alarm)
    old_prof = signal.signal(signal.SIGPROF, alarm)
    signal.setitimer(signal.ITIMER_PROF, HANG_SECONDS)
    signal.alarm(HANG_WALL)
    start = time.monotonic()
    rc: int | None = None
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = main(argv)
    except SystemExit as exc:
        rc = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
        if isinstance(exc.code, str):
            err.write(exc.code)
    except _Hang:
        return Outcome(n, argv, "hang", None, f"over {HANG_SECONDS} CPU s or {HANG_WALL} s",
                       time.monotonic() - start)
    except BaseException as exc:
        lines = traceback.format_exception(type(exc), exc, exc.__traceback__)
        return Outcome(n, argv, "traceback", None, "".join(lines[-3:]).strip()[-600:],
                       time.monotonic() - start)
    finally:
        signal.alarm(0)
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGALRM, old)
        signal.signal(signal.SIGPROF, old_prof)
    seconds = time.monotonic() - start
    message = err.getvalue().strip()
    if rc != 0 and not message and not _answered(argv, rc, out.getvalue()):
        return Outcome(n, argv, "silent", rc, out.getvalue()[-200:], seconds)
    if reader and _tree(run) != before:
        return Outcome(n, argv, "reader-wrote", rc, message[-200:], seconds)
    if argv[0] in ("edit", "repair") and Path(argv[1]).is_dir():
        from genr8_dist.errors import StoreError
        from genr8_dist.store import RunStore

        try:
            problems = RunStore.open(argv[1]).verify()
        except StoreError as exc:
            problems = [str(exc)]
        if argv[0] == "edit" and problems:
            return Outcome(n, argv, "store-damaged", rc, problems[0][-300:], seconds)
        if argv[0] == "repair" and rc == 0 and problems:
            return Outcome(n, argv, "store-damaged", rc, problems[0][-300:], seconds)
    last = message.splitlines()[-1][-200:] if message else ""
    return Outcome(n, argv, "ok" if rc == 0 else "error", rc, last, seconds)


# --- the worker and the driver ------------------------------------------------------------------------

def worker(seed: int, work: Path, run: Path) -> None:
    """Read input numbers on stdin, answer one JSON line each."""
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    os.environ["MPLBACKEND"] = "Agg"
    for line in sys.stdin:
        n = int(line)
        try:
            argv = draw(n, seed, work, run)
            outcome = run_one(n, argv, run)
        except BaseException as exc:
            outcome = Outcome(n, [], "traceback", None, f"harness: {type(exc).__name__}: {exc}"[-600:])
        print(json.dumps(outcome.__dict__), flush=True)


def build_fixture(path: Path) -> None:
    """The small real run the history commands, edit and repair are fuzzed on."""
    sys.path.insert(0, str(ROOT / "tests" / "history"))
    from history_runs import build_real_run

    build_real_run(path)


def fuzz(inputs: int, seed: int, *, first: int = 0, out: Any = None, verbose: bool = False) -> dict[str, Any]:
    """Run inputs ``first .. first + inputs - 1``; the counts of every outcome and the failing inputs."""
    out = out if out is not None else sys.stdout
    with tempfile.TemporaryDirectory(prefix="genr8-fuzz-") as tmp:
        work = Path(tmp)
        run = work / "fixture"
        build_fixture(run)
        counts: dict[str, int] = {}
        failures: list[dict[str, Any]] = []
        proc = None
        start = time.monotonic()
        n = first
        while n < first + inputs:
            if proc is None:
                proc = subprocess.Popen(
                    [sys.executable, "-m", "tests.fuzz.harness", "--worker", "--seed", str(seed),
                     "--work", str(work), "--run", str(run)],
                    cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                    env={**os.environ, "PYTHONPATH": str(ROOT)})
            assert proc.stdin is not None and proc.stdout is not None
            proc.stdin.write(f"{n}\n")
            proc.stdin.flush()
            reply = _read_line(proc, HANG_WALL + 60)
            if reply is None:
                proc.kill()
                proc.wait()
                proc = None
                result = {"n": n, "argv": "?", "kind": "traceback",
                          "detail": "the worker died or stopped answering"}
            else:
                result = json.loads(reply)
            counts[result["kind"]] = counts.get(result["kind"], 0) + 1
            if verbose:
                print(f"#{n} genr8 {' '.join(map(repr, result['argv']))}\n    {result['kind']} "
                      f"(exit {result.get('rc')}): {result['detail']}", file=out, flush=True)
            if result["kind"] not in ("ok", "error"):
                failures.append(result)
                args = " ".join(map(str, result["argv"]))
                print(f"{result['kind']}: #{n} genr8 {args}\n    {result['detail']}", file=out, flush=True)
            n += 1
        if proc is not None:
            proc.stdin.close()  # type: ignore[union-attr]
            proc.wait()
        return {"inputs": inputs, "seed": seed, "counts": counts, "failures": failures,
                "seconds": round(time.monotonic() - start, 1)}


def _read_line(proc: subprocess.Popen, timeout: float) -> str | None:
    import selectors

    assert proc.stdout is not None
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stdout, selectors.EVENT_READ)
        if not sel.select(timeout):
            return None
    line = proc.stdout.readline()
    return line or None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.fuzz.harness", description=__doc__.splitlines()[0])
    parser.add_argument("--inputs", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--first", type=int, default=0, help="start at this input number")
    parser.add_argument("--case", type=int, default=None, metavar="N",
                        help="replay input N alone and print how it ended (also GENR8_FUZZ_CASE=N)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--work", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--run", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        worker(args.seed, args.work, args.run)
        return 0
    case = args.case if args.case is not None else (int(os.environ["GENR8_FUZZ_CASE"])
                                                     if os.environ.get("GENR8_FUZZ_CASE") else None)
    if case is not None:
        report = fuzz(1, args.seed, first=case, verbose=True)
        return 0 if not report["failures"] else 1
    report = fuzz(args.inputs, args.seed, first=args.first)
    kinds = ["ok", "error", "traceback", "hang", "silent", "reader-wrote", "store-damaged"]
    print(f"{report['inputs']} inputs (seed {report['seed']}) in {report['seconds']} s: "
          + ", ".join(f"{k} {report['counts'].get(k, 0)}" for k in kinds))
    return 0 if not report["failures"] else 1


if __name__ == "__main__":
    sys.exit(main())
