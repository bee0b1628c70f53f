"""Finding universes: built-ins, shipped plugins, GENR8_PLUGINS, entry points, paths."""

from __future__ import annotations

import importlib.metadata
import sys
import types
from pathlib import Path

import pytest

from genr8_dist.errors import UniverseError
from genr8_dist.grammar import ENTRY_POINT_GROUP, list_universes, load_universe

MINI = ('//@ description a tiny test universe\nstart: EDGE "+" EDGE "+" EDGE\nEDGE: /Edge[0-9]+/\n'
        '%ignore " "\n')


def plugin(root: Path, name: str, text: str = MINI) -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    (folder / f"{name}.lark").write_text(text)
    return folder


def test_built_ins_and_the_shipped_plugin_are_listed():
    infos = {i.name: i for i in list_universes()}
    for name in ("default", "reversible", "symmetric", "probabilistic"):
        assert infos[name].origin == "built-in"
        assert infos[name].path.name == f"{name}.lark"
        assert infos[name].description
    assert "hemls" not in infos  # the parser's language is not a universe
    assert infos["timed"].origin.startswith("plugin:")
    u = load_universe("timed")
    assert u.origin.startswith("plugin:") and u.hooks is not None


def test_genr8_plugins_folders_are_searched(tmp_path, monkeypatch):
    plugin(tmp_path / "many", "mini")
    single = plugin(tmp_path, "solo")
    monkeypatch.setenv("GENR8_PLUGINS", f"{tmp_path / 'many'}{__import__('os').pathsep}{single}")
    infos = {i.name: i for i in list_universes()}
    assert infos["mini"].origin == f"plugin:{tmp_path / 'many' / 'mini'}"
    assert infos["solo"].description == "a tiny test universe"
    u = load_universe("mini")
    assert u.name == "mini" and u.map([0, 1]).text == "Edge1 + Edge0 + Edge1"


def test_the_current_directory_is_never_searched(tmp_path, monkeypatch):
    """A copied run or a download holding plugins/ runs nothing: only GENR8_PLUGINS is searched."""
    folder = plugin(tmp_path / "plugins", "local")
    (folder / "hooks.py").write_text("raise SystemExit('ran code from the current directory')\n")
    monkeypatch.chdir(tmp_path)
    assert "local" not in {i.name for i in list_universes()}
    with pytest.raises(UniverseError, match=r"unknown universe 'local'"):
        load_universe("local")


def test_a_built_in_name_cannot_be_taken_by_a_plugin(tmp_path, monkeypatch):
    plugin(tmp_path, "default")
    monkeypatch.setenv("GENR8_PLUGINS", str(tmp_path))
    assert load_universe("default").origin == "built-in"


def test_entry_points_give_universes(tmp_path, monkeypatch):
    lark = tmp_path / "ep.lark"
    lark.write_text(MINI)
    module = types.ModuleType("fake_genr8_universes")
    module.by_function = lambda: lark
    module.folder = plugin(tmp_path, "foldered")
    monkeypatch.setitem(sys.modules, "fake_genr8_universes", module)
    eps = [importlib.metadata.EntryPoint("by_path", str(lark), ENTRY_POINT_GROUP),
           importlib.metadata.EntryPoint("by_function", "fake_genr8_universes:by_function",
                                         ENTRY_POINT_GROUP),
           importlib.metadata.EntryPoint("by_folder", "fake_genr8_universes:folder", ENTRY_POINT_GROUP)]
    real = importlib.metadata.entry_points

    def fake(**kwargs):
        if kwargs.get("group") == ENTRY_POINT_GROUP:
            return eps
        return real(**kwargs)

    monkeypatch.setattr(importlib.metadata, "entry_points", fake)
    for name in ("by_path", "by_function", "by_folder"):
        u = load_universe(name)
        assert u.origin.startswith("entry point:")
        assert u.map([5, 2]).text == "Edge2 + Edge1 + Edge2"


def test_paths_to_files_and_folders(tmp_path):
    folder = plugin(tmp_path, "pathy")
    by_file = load_universe(str(folder / "pathy.lark"))
    by_folder = load_universe(str(folder))
    assert by_file.origin == by_folder.origin == "path"
    assert by_file.name == by_folder.name == "pathy"


def test_compiled_universes_are_cached_and_reloaded_when_the_file_changes(tmp_path):
    folder = plugin(tmp_path, "cached")
    first = load_universe(str(folder))
    assert load_universe(str(folder)) is first
    assert load_universe("default") is load_universe("default")
    (folder / "cached.lark").write_text(MINI.replace('"+" EDGE\n', '"+" EDGE "+" EDGE\n'))
    assert load_universe(str(folder)).map([0, 0]).text == "Edge0 + Edge0 + Edge0 + Edge0"


@pytest.mark.parametrize("name, pattern", [
    ("nope", r"unknown universe 'nope' \(known: default, .*reversible.*\)"),
    ("missing/universe.lark", r"missing/universe.lark: no such universe file"),
    ("", r"non-empty"),
])
def test_unknown_universes(name, pattern):
    with pytest.raises(UniverseError, match=pattern):
        load_universe(name)


def test_plugin_hooks_that_fail_to_import_are_reported(tmp_path):
    folder = plugin(tmp_path, "broken")
    (folder / "hooks.py").write_text("import no_such_module_anywhere\n")
    with pytest.raises(UniverseError, match=r"broken/hooks.py:1: importing the plugin's hooks.py failed: "
                       r"ModuleNotFoundError: No module named 'no_such_module_anywhere'$"):
        load_universe(str(folder))


def test_timed_repair_hook_gives_every_label_an_unconditioned_rule():
    u = load_universe("timed")
    checked = 0
    for seed in range(40):
        genome = [(seed * 7919 + i * 104729) % 65536 for i in range(200)]
        result = u.map(genome)
        if not result.valid:
            continue
        checked += 1
        lines = result.text.splitlines()
        free = set()
        for line in lines:
            if "->" in line and " If " not in line:
                pred = line.split("->")[0]
                pred = pred.split("<")[-1]
                free.add(u.label_of(pred.split()[0]))
        labels = {u.label_of(w) for w in result.text.split()} - {None}
        assert labels <= free
    assert checked > 30
