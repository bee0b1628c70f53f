"""docs/ARCHITECTURE.md's module table names every module of the package, so a newcomer finds each
concept's home from the table."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "genr8_dist"


def _table() -> dict[str, set[str]]:
    """The table's rows: first cell (``config.py`` or ``grammar/``) -> the names its concept cell
    puts in backticks (``compiler``, ``_kernels.KernelSwitch`` counts as ``_kernels``)."""
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text(encoding="utf-8")
    section = text.split("## Which module holds each concept", 1)[1].split("\n## ", 1)[0]
    rows: dict[str, set[str]] = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 2 or not cells[0].startswith("`"):
            continue
        named = {token.split(".")[0].split(" ")[0] for token in re.findall(r"`([^`]+)`", cells[1])}
        rows[cells[0].strip("`")] = named
    return rows


def _missing() -> list[str]:
    rows = _table()
    missing = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if rel.name in ("__init__.py", "__main__.py"):
            continue
        if len(rel.parts) == 1:
            if rel.name not in rows:
                missing.append(f"genr8_dist/{rel}: add a row `{rel.name}`")
            continue
        package = "/".join(rel.parts[:-1]) + "/"
        if package not in rows:
            missing.append(f"genr8_dist/{rel}: add a row `{package}`")
        elif rel.stem not in rows[package]:
            missing.append(f"genr8_dist/{rel}: name `{rel.stem}` in the `{package}` row")
    return missing


def test_the_module_table_names_every_module():
    missing = _missing()
    assert not missing, "docs/ARCHITECTURE.md's module table lacks:\n" + "\n".join(missing)


def test_the_module_table_names_no_module_that_is_gone():
    rows = _table()
    gone = [name for name in rows if not (PACKAGE / name).exists()]
    assert not gone, f"docs/ARCHITECTURE.md's module table has rows for missing modules: {gone}"
