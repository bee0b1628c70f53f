"""The README's worked examples do what the README says they do."""

from __future__ import annotations

import io
import json
import re
import shlex
from pathlib import Path

import pytest

from genr8_dist.cli import main

README = (Path(__file__).resolve().parents[2] / "README.md").read_text()


def _command(pattern: str) -> list[str]:
    line = next(line.strip() for line in README.splitlines() if re.search(pattern, line))
    return shlex.split(line.split("#")[0])[1:]


def test_the_genome_example_maps_validly(capsys):
    argv = _command(r"genr8 map --universe default --genome .* --json")
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["valid"] is True and out["text"].count("->") >= 2


def test_the_pipe_example_grows_a_surface_that_changes(monkeypatch, tmp_path, capsys):
    line = next(line.strip() for line in README.splitlines()
                if re.search(r"genr8 map .*\| genr8 grow -", line))
    mapped, grown = (shlex.split(part)[1:] for part in line.split("#")[0].split("|"))
    assert main(mapped) == 0
    text = capsys.readouterr().out
    monkeypatch.setattr("sys.stdin", io.StringIO(text))
    grown = [str(tmp_path / a) if a.endswith(".png") else a for a in grown]
    assert main(grown) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines() if line.split()[:1] != []
            and line.split()[0].isdigit()]
    regions = [int(row[3]) for row in rows]
    assert len(regions) == 4 and regions[-1] >= 16 and regions == sorted(regions)
    assert (tmp_path / "mapped.png").stat().st_size > 10_000


# -- every command block, run as written ----------------------------------------------------------
#
# The blocks are read from the README and docs/*.md themselves (``command_lines``), never copied here.
# A reader has run the README's first command (installed genr8_dist) in a fresh clone; the test is
# that state: the shipped folders copied to a fresh directory, ``genr8`` on the PATH. Then every line
# runs through bash, in order (README, then docs/*.md by name), in that one directory. The only
# departures from "as written", each a thing the reader does by hand:
#   - the install steps (venv, activate, ``pip install``) are this test's environment; ``pytest`` (the
#     suite itself) is not run from inside it; ``python bench/...`` lines print figures over minutes
#     and are left to the benchmarks;
#   - a line whose comment says Ctrl-C runs until it shows it works (a progress line, the studio
#     answering its printed URL), then gets Ctrl-C (SIGINT to its process group, as a terminal sends)
#     and must exit 0;
#   - when port 8765 is taken on the machine running the tests, a studio line gets ``--port 0``.

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ("examples", "plugins", "grammars", "bench", "docs", "cluster", "README.md", "pyproject.toml")
COMMANDS = ("genr8", "python", "python3", "pip", "pytest", ".")
INSTALL = re.compile(r"^(python3? -m venv |\. \S*activate$|pip install )")
READY = re.compile(r"^(gen +\d+/\d+ |studio: (?P<url>http\S+))", re.M)


def _split_comment(line: str) -> tuple[str, str]:
    """``line`` as (command, comment): the comment starts at a ``#`` after a blank, outside quotes."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i].rstrip(), line[i + 1:].strip()
    return line.rstrip(), ""


def _is_command(line: str) -> bool:
    word = line.split(maxsplit=1)[0] if line.split() else ""
    return word in COMMANDS


def command_lines(markdown: str) -> list[str]:
    """The shell commands of a Markdown text's command blocks, in order: fenced blocks (no language,
    ``bash``, ``sh`` or ``shell``) and 4-space indented blocks, each line that starts with a command."""
    out: list[str] = []
    fence: str | None = None
    previous_blank = True
    in_indented = False
    for raw in markdown.splitlines():
        if raw.startswith("```"):
            fence = raw[3:].strip() if fence is None else None
            continue
        if fence is not None:
            if fence in ("", "bash", "sh", "shell") and _is_command(raw.strip()):
                out.append(raw.strip())
            continue
        if raw.startswith("    ") and (previous_blank or in_indented):
            in_indented = True
            if _is_command(raw.strip()):
                out.append(raw.strip())
        else:
            in_indented = False
        previous_blank = not raw.strip()
    return out


def _markdown_files() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def runnable(line: str) -> str | None:
    """The part of a documented line this test runs (see the header above), None for none of it."""
    command, _ = _split_comment(line)
    if command.startswith("python bench/"):
        return None
    parts = [p.strip() for p in command.split("&&")]
    kept = [p for p in parts if not INSTALL.match(p) and p != "pytest" and not p.startswith("pytest ")]
    return " && ".join(kept) or None


def test_the_blocks_are_found_and_name_only_runs_and_files_an_earlier_line_made():
    """Fast: what the slow test runs, checked statically. A run directory is created once (by
    ``--run-dir``) before any line reads it; an input file is shipped or written by an earlier line."""
    made_runs: set[str] = set()
    made_files: set[str] = set()
    seen = 0
    for path in _markdown_files():
        for line in command_lines(path.read_text()):
            command = runnable(line)
            if command is None:
                continue
            seen += 1
            for part in command.split("|"):
                words = shlex.split(part)
                if ">" in words:
                    made_files.add(words[words.index(">") + 1])
                if "--run-dir" in words:
                    run = words[words.index("--run-dir") + 1]
                    assert run not in made_runs, f"{path.name}: {line!r}: {run} already holds a run"
                    made_runs.add(run)
                for word in words[1:]:
                    if word.startswith("runs/") and word not in made_runs and "--run-dir" not in words:
                        raise AssertionError(f"{path.name}: {line!r}: no earlier line made {word}")
                    if re.search(r"\.(hemls|txt)$", word) and words[words.index(word) - 1] != ">":
                        assert word in made_files or (ROOT / word).exists(), \
                            f"{path.name}: {line!r}: {word} is neither shipped nor made by an earlier line"
    assert seen >= 30


def _port_free(port: int) -> bool:
    import socket

    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def _fetch(url: str) -> tuple[int, str]:
    import urllib.request

    with urllib.request.urlopen(url, timeout=30) as reply:
        return reply.status, reply.read().decode("utf-8", "replace")


def _run_interrupted(command: str, cwd: Path, env: dict[str, str], limit: float) -> str:
    """Run ``command`` until it shows it works, then Ctrl-C it (again if it says it stays open)."""
    import os
    import signal
    import subprocess
    import threading
    import time

    proc = subprocess.Popen(["bash", "-c", command], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(proc.stdout.readline, "")), daemon=True)
    reader.start()
    deadline = time.monotonic() + limit
    try:
        wants_progress = not command.startswith("genr8 studio")
        wants_studio = "--studio" in command or not wants_progress
        url = None
        while time.monotonic() < deadline and proc.poll() is None:
            text = "".join(lines)
            found = {m.group(0)[:3]: m for m in READY.finditer(text)}
            url = found["stu"].group("url") if "stu" in found else None
            if ("gen" in found or not wants_progress) and (url or not wants_studio):
                break
            time.sleep(0.5)
        assert proc.poll() is None, f"{command!r} ended before Ctrl-C:\n{''.join(lines)}"
        assert time.monotonic() < deadline, f"{command!r} showed nothing in {limit:.0f} s:\n{''.join(lines)}"
        if url:
            status, page = _fetch(url)
            assert status == 200 and "<html" in page.lower()
        os.killpg(proc.pid, signal.SIGINT)
        sent = 1
        while time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.5)
            if sent == 1 and "Ctrl-C closes it" in "".join(lines):
                os.killpg(proc.pid, signal.SIGINT)
                sent = 2
        assert proc.poll() is not None, f"{command!r} did not stop after Ctrl-C:\n{''.join(lines)}"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    reader.join(timeout=10)
    out = "".join(lines)
    assert proc.returncode == 0, f"{command!r} exited {proc.returncode} after Ctrl-C:\n{out}"
    return out


@pytest.mark.slow
@pytest.mark.timeout(3600)   # three runs (quick, a bowl interrupted twice, tables) and the regrowth after
def test_every_command_block_of_the_readme_and_docs_runs_as_written_in_order(tmp_path):
    import os
    import shutil
    import subprocess
    import sys

    for name in SHIPPED:
        source = ROOT / name
        if source.is_dir():
            shutil.copytree(source, tmp_path / name, ignore=shutil.ignore_patterns("__pycache__", "runs"))
        else:
            shutil.copy(source, tmp_path / name)
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1",
               PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    free = _port_free(8765)
    outputs: dict[str, str] = {}
    for path in _markdown_files():
        for line in command_lines(path.read_text()):
            command = runnable(line)
            if command is None:
                continue
            if "studio" in command.split("#")[0] and not free:
                command += " --studio-port 0" if " run " in f" {command} " else " --port 0"
            if "Ctrl-C" in _split_comment(line)[1]:
                outputs[line] = _run_interrupted(command, tmp_path, env, limit=900)
                continue
            done = subprocess.run(["bash", "-c", command], cwd=tmp_path, env=env, capture_output=True,
                                  text=True, timeout=1200)
            assert done.returncode == 0, (f"{path.name}: {line!r} exited {done.returncode}:\n"
                                          f"{done.stdout[-3000:]}\n{done.stderr[-3000:]}")
            outputs[line] = done.stdout
    # what the lines promise is there
    for name in ("quick-report.html", "report.html", "best.obj", "best.3dm", "best.png", "tree.png",
                 "curves.png", "gallery.png", "kinds.png", "tiles.obj", "drape.glb", "edges.obj",
                 "sq-step4.ply", "table.stl", "system.txt", "my.hemls"):
        assert (tmp_path / name).stat().st_size > 0, name
    invert = next(out for line, out in outputs.items() if line.startswith("genr8 invert --universe rev"))
    assert re.fullmatch(r"\d+(,\d+)*\n", invert)
    edits = [out for line, out in outputs.items() if line.startswith("genr8 edit runs/bowl")]
    assert len(edits) == 4 and all("configuration version" in out for out in edits)
    resumed = next(out for line, out in outputs.items() if line.startswith("genr8 resume runs/bowl"))
    assert "resuming runs/bowl after generation" in resumed
    assert "resume with: genr8 resume runs/bowl" in resumed
    for run in ("quick", "bowl", "tables", "live"):   # finished or interrupted, no run keeps its lock
        assert (tmp_path / "runs" / run / "_manifest").is_dir()
        assert not (tmp_path / "runs" / run / "_running.lock").exists(), run


def test_the_benchmarks_section_names_every_bench():
    """Each script of bench/ is listed where a user looks for what the project measures."""
    section = README.split("\n## Benchmarks\n", 1)[1].split("\n## ", 1)[0]
    bench = Path(__file__).resolve().parents[2] / "bench"
    missing = [p.name for p in sorted(bench.glob("*.py")) if f"`{p.name}`" not in section]
    assert not missing
