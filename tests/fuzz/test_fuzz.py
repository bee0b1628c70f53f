"""1,000 fuzzed ``genr8`` inputs: each ends with an answer or a one-line error, on time, changing nothing it
should only read (tests/fuzz/harness.py says how inputs are drawn and judged)."""

from __future__ import annotations

import io
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from harness import KINDS, ROOT, _shipped, fuzz, mutate, run_one


@pytest.mark.slow
def test_a_thousand_fuzzed_inputs_end_in_an_answer_or_one_line() -> None:
    log = io.StringIO()
    report = fuzz(1000, seed=1, out=log)
    assert sum(report["counts"].values()) == 1000
    assert report["failures"] == [], log.getvalue()
    assert report["counts"].get("ok", 0) >= 100  # the inputs are not all rejected at the door


def test_mutations_are_seeded() -> None:
    from genr8_dist.rng import stream

    data = b"[ea]\npopulation = 20\ngenerations = 15\n"
    first = [mutate(data, stream(3, "m", k)) for k in range(20)]
    again = [mutate(data, stream(3, "m", k)) for k in range(20)]
    assert first == again
    assert len(set(first)) > 10


def test_every_input_is_the_same_in_another_process(tmp_path: Path) -> None:
    """Input n is drawn from its number alone: a fresh process draws the same arguments and files."""
    code = ("import sys, json, pathlib; sys.path.insert(0, 'tests/fuzz'); from harness import draw; "
            "w = pathlib.Path(sys.argv[1]); w.mkdir(); out = []\n"
            "for n in (0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19):\n"
            "    try: argv = draw(n, 1, w, pathlib.Path('/nonexistent'))\n"
            "    except FileNotFoundError: argv = ['needs the fixture run']\n"
            "    out.append([a.replace(str(w), 'W') for a in argv])\n"
            "files = {p.name: p.read_bytes().hex() for p in sorted(w.iterdir()) if p.is_file()}\n"
            "print(json.dumps([out, files]))")
    runs = [subprocess.run([sys.executable, "-c", code, str(tmp_path / f"w{k}")], cwd=ROOT, check=True,
                           capture_output=True, text=True, env={"PYTHONHASHSEED": str(k), "PATH": "",
                                                                "PYTHONPATH": str(ROOT)}).stdout
            for k in (1, 2)]
    assert runs[0] == runs[1] and len(runs[0]) > 1000


@pytest.mark.parametrize("kind", KINDS)
def test_each_file_kind_corrupted_ends_in_an_answer_or_one_line(kind: str) -> None:
    """Eight seeded corruptions of each shipped file kind through the command that reads it (stored run
    files: tests/store/test_corruption.py, 140 cases, and the harness's ``repair`` family)."""
    from genr8_dist.rng import stream

    square = str(ROOT / "grammars" / "systems" / "square.hemls")
    with tempfile.TemporaryDirectory() as tmp:
        outcomes = []
        for k in range(8):
            source = _shipped(kind)[k % len(_shipped(kind))]
            target = Path(tmp) / f"in-{k}{source.suffix}"
            target.write_bytes(mutate(source.read_bytes(), stream(7, "corrupt", kind, k)))
            argv = {"universe": ["map", "--universe", str(target), "--random"],
                    "system": ["grow", str(target), "--steps", "2"],
                    "env": ["grow", square, "--steps", "1", "--env", str(target)],
                    "config": ["run", str(target), "--run-dir", str(Path(tmp) / f"run-{k}")],
                    "genome": ["map", "--genome", target.read_bytes().decode("utf-8", "replace")
                               .replace("\x00", "")]}[kind]
            outcomes.append(run_one(k, argv, Path(tmp) / "no-run"))
    assert [o.kind for o in outcomes if o.kind not in ("ok", "error")] == [], \
        [(o.argv, o.kind, o.detail) for o in outcomes]
    assert all(o.detail.count("\n") == 0 for o in outcomes)


@pytest.mark.slow
def test_a_case_is_replayed_alone_by_its_number() -> None:
    done = subprocess.run([sys.executable, "-m", "tests.fuzz.harness", "--case", "5", "--seed", "1"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"})
    assert done.returncode == 0, done.stdout + done.stderr
    first, second = done.stdout.splitlines()[:2]
    assert first.startswith("#5 genr8 ") and second.strip().startswith(("ok", "error"))
