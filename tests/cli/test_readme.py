"""The README's worked examples do what the README says they do."""

from __future__ import annotations

import io
import json
import re
import shlex
from pathlib import Path

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
