"""The genr8 dispatcher: help, version, and errors as one line with exit status 2."""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from genr8_dist import __version__, cli
from genr8_dist.errors import ConfigError, ParseError


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0
    assert __version__ in capsys.readouterr().out


def test_no_command_prints_help(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main([]) == 2
    assert "usage: genr8" in capsys.readouterr().out


def _parser_with(handler):  # a dispatcher whose one command runs `handler`
    parser = argparse.ArgumentParser(prog="genr8")
    parser.set_defaults(handler=handler)
    return parser


@pytest.mark.parametrize(
    ("exc", "expected"),
    [(ConfigError("env.toml: field 'scale': must be > 0, got -1"),
      "genr8: error: env.toml: field 'scale': must be > 0, got -1"),
     (ParseError("expected '->'", source="a.hemls", line=3, column=7),
      "genr8: error: a.hemls:3:7: expected '->'"),
     (FileNotFoundError(2, "No such file or directory", "missing.toml"),
      "genr8: error: missing.toml: No such file or directory")],
)
def test_errors_are_one_line_and_exit_2(monkeypatch, capsys, exc, expected) -> None:
    def handler(args):
        raise exc

    monkeypatch.setattr(cli, "build_parser", lambda: _parser_with(handler))
    assert cli.main([]) == 2
    err = capsys.readouterr().err
    assert err == expected + "\n"


def test_help_does_not_import_heavy_packages() -> None:
    code = ("import sys; from genr8_dist.cli import build_parser; build_parser(); "
            "print(sorted(m for m in ('ray', 'pyarrow', 'trimesh', 'matplotlib', 'duckdb') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
