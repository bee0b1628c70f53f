"""Where the files that ship with genr8_dist live: built-in universes, predefined systems, plugins.

An installed wheel carries them inside the package (``genr8_dist/_data``); a source checkout has them
at the top of the repository. Both are found the same way, so ``pip install .`` and an editable
install behave alike.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["grammars_dir", "plugins_dir", "systems_dir"]

_PACKAGE = Path(__file__).resolve().parent


def _data(name: str) -> Path:
    installed = _PACKAGE / "_data" / name
    if installed.is_dir():
        return installed
    return _PACKAGE.parent / name


def grammars_dir() -> Path:
    """The folder of the built-in universes (``*.lark``) and ``hemls.lark``."""
    return _data("grammars")


def systems_dir() -> Path:
    """The folder of the predefined rewrite systems (``*.hemls``)."""
    return grammars_dir() / "systems"


def plugins_dir() -> Path:
    """The folder of the plugin universes shipped with genr8_dist (one sub-folder each)."""
    return _data("plugins")
