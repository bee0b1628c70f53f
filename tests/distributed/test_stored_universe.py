"""A run carries its universe: a plugin's grammar and hooks are stored in the run's configuration, so
the run can be resumed, edited, shown, reported and queried after the plugin is gone; code stored in a
run directory never runs for history commands, and runs for ``resume``/``edit`` only with consent."""

from __future__ import annotations

import contextlib
import io
import shutil
import sys
import tomllib
from pathlib import Path

import pytest
from distributed_runs import rows
from plugin_universe import make_plugin

from genr8_dist.cli import main
from genr8_dist.grammar import trust

CONFIG = """\
universe = "{universe}"
seed = 5

[genome]
length = 40
max_depth = 4

[ea]
population = 6
generations = 2
tournament = 2

[environment]
steps = 2

[islands]
count = 2
migration_interval = 2
migrants = 1
"""

HISTORY_COMMANDS = [["history"], ["top", "-k", "3"], ["lineage", "0-2-0"], ["show", "0-2-0"],
                    ["query", "select count(*) as n from individuals"],
                    ["report", "--output", "{out}/r.html"], ["gallery", "--output", "{out}/g.png"]]


@pytest.fixture
def fresh_trust(tmp_path, monkeypatch):
    """A machine that has trusted nothing: an empty trust file and no consent in this process."""
    monkeypatch.setenv("GENR8_TRUST_FILE", str(tmp_path / "trusted-hooks"))
    monkeypatch.setattr(trust, "_CONSENTED", set())
    return tmp_path / "trusted-hooks"


def cli(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main([str(a) for a in argv])
    return status, out.getvalue(), err.getvalue()


def forget_consent(monkeypatch, trust_file: Path) -> None:
    """What another machine sees: nothing trusted, nothing consented."""
    trust_file.unlink(missing_ok=True)
    monkeypatch.setattr(trust, "_CONSENTED", set())


def start_plugin_run(tmp_path: Path, marker: Path | None = None) -> tuple[Path, Path]:
    """A finished 2-island run of the plugin ``selfsim`` named by a path relative to the TOML's folder
    (the command runs from another directory); returns (run dir, plugin folder)."""
    plugin = make_plugin(tmp_path / "downloads", marker=marker)
    configs = tmp_path / "configs"
    configs.mkdir()
    toml = configs / "run.toml"
    toml.write_text(CONFIG.format(universe="../downloads/selfsim"))
    run_dir = tmp_path / "run"
    status, _out, err = cli("run", toml, "--run-dir", run_dir, "--quiet", "--trust-hooks")
    assert status == 0, err
    return run_dir, plugin


@pytest.mark.slow
def test_a_plugin_run_outlives_its_plugin(tmp_path, ray_local, fresh_trust, monkeypatch):
    run_dir, plugin = start_plugin_run(tmp_path)
    stored = tomllib.loads(next((run_dir / "configs").glob("v0001*.toml")).read_text())
    assert stored["universe"] == "selfsim"
    files = stored["stored_universe"]["files"]
    assert sorted(files) == ["hooks.py", "selfsim.lark"]
    assert files["hooks.py"] == (plugin / "hooks.py").read_text()
    texts = [r["text"] for r in rows(run_dir) if r["text"]]
    assert texts and all("Angle 45" in t for t in texts)   # the plugin's hook ran on every host
    before = rows(run_dir)

    shutil.rmtree(plugin.parent)                             # the plugin is gone
    monkeypatch.chdir(tmp_path)
    for argv in HISTORY_COMMANDS:
        status, _out, err = cli(*[a.format(out=tmp_path) for a in argv[:1]], run_dir,
                               *[a.format(out=tmp_path) for a in argv[1:]])
        assert status == 0, (argv, err)
    system = tmp_path / "system.hemls"
    system.write_text(next(t for t in texts))
    status, _out, err = cli("edit", run_dir, "--generations", "2", "--inject-text", system)
    assert status == 0, err
    status, _out, err = cli("resume", run_dir, "--quiet")
    assert status == 0, err
    after = rows(run_dir)
    assert [r for r in after if r["generation"] <= 2] == before
    assert max(r["generation"] for r in after) == 4
    assert any(r["origin"] == "injected" for r in after)
    assert all("Angle 45" in r["text"] for r in after if r["text"])


@pytest.mark.slow
def test_a_plugin_named_by_a_toml_path_runs_once_consented_then_is_trusted(tmp_path, ray_local, fresh_trust):
    start_plugin_run(tmp_path)   # with --trust-hooks: the digest is now remembered
    assert len(fresh_trust.read_text().splitlines()) == 1
    toml = tmp_path / "configs" / "run.toml"
    status, _out, err = cli("run", toml, "--run-dir", tmp_path / "again", "--quiet")
    assert status == 0 and err == ""


def test_a_plugin_named_by_a_toml_path_does_not_run_without_consent(tmp_path, fresh_trust, monkeypatch):
    """No --trust-hooks and no terminal: one line, exit 2, its hooks.py never imported, nothing
    remembered and no run directory made."""
    marker = tmp_path / "MARKER"
    plugin = make_plugin(tmp_path / "downloads", marker=marker)
    toml = tmp_path / "run.toml"
    toml.write_text(CONFIG.format(universe="./downloads/selfsim"))
    monkeypatch.setattr("sys.stdin", io.StringIO("y\n"))   # not a terminal: never asked, a yes unread
    status, out, err = cli("run", toml, "--run-dir", tmp_path / "r", "--quiet")
    assert status == 2 and out == ""
    (line,) = err.splitlines()
    assert line.startswith(f"genr8: error: universe 'selfsim' carries Python code (hooks.py from {plugin}, "
                           "sha256 ")
    assert line.endswith(f"that this machine has not trusted; read it, then run `genr8 run {toml} --run-dir "
                         f"{tmp_path / 'r'} --trust-hooks` (the trust rule: docs/run-store.md)")
    assert not marker.exists() and not (tmp_path / "r").exists()
    assert not fresh_trust.exists()


def test_a_yes_at_the_terminal_prompt_is_consent_and_a_no_refuses(tmp_path, fresh_trust, monkeypatch, capsys):
    from genr8_dist.errors import UniverseError
    from genr8_dist.grammar.discovery import consent_for_new_run, find_source

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    make_plugin(tmp_path / "downloads")
    source, origin = find_source(str(tmp_path / "downloads" / "selfsim"))
    assert origin == "path"
    monkeypatch.setattr("sys.stderr", Terminal())
    monkeypatch.setattr("sys.stdin", Terminal("n\n"))
    with pytest.raises(UniverseError, match="has not trusted"):
        consent_for_new_run(source, trust_flag=False)
    assert not trust.may_run(source.code_digest) and not fresh_trust.exists()
    monkeypatch.setattr("sys.stdin", Terminal("y\n"))
    consent_for_new_run(source, trust_flag=False)
    assert trust.may_run(source.code_digest)
    assert fresh_trust.read_text().split()[0] == source.code_digest
    assert "run it, and trust it from now on? [y/N]" in sys.stderr.getvalue()


def test_map_and_invert_run_a_plugin_folder_given_by_a_path_only_with_consent(tmp_path, fresh_trust):
    marker = tmp_path / "MARKER"
    plugin = make_plugin(tmp_path / "downloads", marker=marker)
    status, out, err = cli("map", "--universe", plugin, "--random")
    assert status == 2 and out == "" and len(err.splitlines()) == 1
    assert "has not trusted" in err and f"`genr8 map --universe {plugin} --trust-hooks`" in err
    assert not marker.exists()
    status, out, err = cli("map", "--universe", plugin, "--random", "--trust-hooks")
    assert status in (0, 1) and out and marker.exists(), err
    trust._CONSENTED.clear()    # a later command: the digest was trusted by that consent
    status, out, err = cli("map", "--universe", plugin, "--random")
    assert status in (0, 1) and out, err


def test_a_note_is_not_consent_for_a_copied_run(tmp_path, fresh_trust):
    """The code a run directory carries is refused for resume unless its digest was trusted by
    consent: a refused run left nothing remembered."""
    make_plugin(tmp_path / "downloads")
    toml = tmp_path / "run.toml"
    toml.write_text(CONFIG.format(universe="./downloads/selfsim"))
    assert cli("run", toml, "--run-dir", tmp_path / "r", "--quiet")[0] == 2
    assert not fresh_trust.exists() and trust.remembered() == set()


@pytest.mark.slow
def test_planted_and_altered_hooks_never_run_for_history_and_resume_needs_consent(
        tmp_path, ray_local, fresh_trust, monkeypatch):
    marker = tmp_path / "MARKER"
    run_dir, plugin = start_plugin_run(tmp_path, marker=marker)
    assert marker.exists()          # the user's own run: its hooks ran (after the notice)
    marker.unlink()
    shutil.rmtree(plugin.parent)
    forget_consent(monkeypatch, fresh_trust)   # the run directory is copied to another machine

    for argv in HISTORY_COMMANDS:
        status, _out, err = cli(argv[0], run_dir, *[a.format(out=tmp_path) for a in argv[1:]])
        assert status == 0, (argv, err)
    assert not marker.exists()
    status, _out, err = cli("edit", run_dir, "--generations", "1")   # no code needed: allowed
    assert status == 0, err
    assert not marker.exists()

    status, _out, err = cli("resume", run_dir, "--quiet")
    assert status == 2
    (line,) = err.splitlines()
    assert line.startswith("genr8: error: ") and "carries Python code (hooks.py, sha256" in line
    assert f"genr8 resume {run_dir} --trust-hooks" in line
    assert not marker.exists()
    system = tmp_path / "s.hemls"
    system.write_text(rows(run_dir)[0]["text"])
    status, _out, err = cli("edit", run_dir, "--inject-text", system)
    assert status == 2 and "--trust-hooks" in err and not marker.exists()

    # altered: a configuration version whose stored hooks differ from the trusted ones
    from genr8_dist.store import RunStore

    store = RunStore.open(run_dir)
    data = tomllib.loads(store.configs()[-1].toml)
    files = data["stored_universe"]["files"]
    files["hooks.py"] += "\n# altered\n"
    from genr8_dist.grammar.source import UniverseSource

    data["stored_universe"]["digest"] = UniverseSource("selfsim", tuple(files.items())).digest
    import tomli_w

    status, _out, err = cli("resume", run_dir, "--quiet", "--trust-hooks")   # trust the original
    assert status == 0, err
    assert marker.exists()
    marker.unlink()
    store = RunStore.open(run_dir)
    done = max(store.committed_generations().values())
    data["ea"]["generations"] = done + 1
    store.add_config(tomli_w.dumps(data), done + 1)
    for argv in HISTORY_COMMANDS[:3]:
        assert cli(argv[0], run_dir, *argv[1:])[0] == 0
    status, _out, err = cli("resume", run_dir, "--quiet")
    assert status == 2 and "has not trusted" in err
    assert not marker.exists()


def test_a_stored_universe_whose_files_were_altered_is_refused(tmp_path):
    from genr8_dist.config import RunConfig
    from genr8_dist.errors import ConfigError

    config = RunConfig(universe="default")
    data = config.to_dict()
    assert data["stored_universe"]["name"] == "default"
    assert RunConfig.from_dict(data) == config
    data["stored_universe"]["files"]["default.lark"] += "\n// changed\n"
    with pytest.raises(ConfigError, match=r"stored universe's digest .* does not match its files"):
        RunConfig.from_dict(data)
