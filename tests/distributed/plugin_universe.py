"""A plugin universe for the tests of a run that carries its universe: ``selfsim``, the default
grammar plus a ``hooks.py`` whose repair hook also turns every ``Angle 30`` into ``Angle 45`` (so rows
show whether the plugin's code ran), optionally leaving a marker file when it is imported."""

from __future__ import annotations

from pathlib import Path

HOOKS = '''"""selfsim's hooks: the built-in HEMLS repair, then every Angle 30 becomes Angle 45."""

from genr8_dist.grammar.hooks import hemls_repair
{marker}

def repair(ctx):
    hemls_repair(ctx)
    ctx.text = ctx.text.replace("Angle 30", "Angle 45")
'''

MARKER = '''
import pathlib as _pathlib
_pathlib.Path({path!r}).write_text("hooks.py ran")
'''


def make_plugin(root: Path, name: str = "selfsim", marker: Path | None = None) -> Path:
    """A plugin folder ``root/name`` holding ``name.lark`` and ``hooks.py``; returns the folder."""
    from genr8_dist.resources import grammars_dir

    folder = root / name
    folder.mkdir(parents=True, exist_ok=True)
    grammar = (grammars_dir() / "default.lark").read_text(encoding="utf-8")
    grammar = grammar.replace("//@ description Genr8's default EA universe",
                              "//@ description selfsim, a test plugin")
    (folder / f"{name}.lark").write_text(grammar, encoding="utf-8")
    extra = MARKER.format(path=str(marker)) if marker is not None else ""
    (folder / "hooks.py").write_text(HOOKS.format(marker=extra), encoding="utf-8")
    return folder
