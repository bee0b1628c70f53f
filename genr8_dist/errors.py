"""The exceptions genr8_dist raises on bad input, all under one root.

Genr8Error
├── ConfigError (also ValueError)     a TOML or command-line value is wrong: names the field
├── UniverseError                     a universe cannot be found or its .lark file is malformed
├── GenomeError (also ValueError)     a genome is empty or holds negative or non-integer codons
├── InversionError                    a text cannot be turned back into a genome
├── ParseError                        a rewrite system's text is malformed: names line and column
├── GrowthError                       growth cannot start (e.g. a boundary mesh cannot be read)
├── StoreError                        a run directory is missing, not a run, or corrupt
├── HistoryError (also ValueError)    a history request names an id, criterion or generation the run
│                                     lacks, or its SQL is malformed
└── RunError                          a run cannot be scheduled, or its cluster cannot be reached

A failed *individual* (it cannot be mapped, grown or scored) is not an exception: it is recorded as
data with its reason (see ``genr8_dist.evolution``). Every message is one line; the command line
prints it after ``genr8: error:`` and exits with status 2.
"""

from __future__ import annotations

__all__ = [
    "ConfigError",
    "GenomeError",
    "Genr8Error",
    "GrowthError",
    "HistoryError",
    "InversionError",
    "ParseError",
    "RunError",
    "StoreError",
    "UniverseError",
    "located",
]


class Genr8Error(Exception):
    """Root of every error genr8_dist raises on purpose."""


class ConfigError(Genr8Error, ValueError):
    """A configuration value is wrong; the message names the field, the value and what is allowed."""


class UniverseError(Genr8Error):
    """A universe is unknown, or its grammar file breaks the universe conventions."""


class GenomeError(Genr8Error, ValueError):
    """A genome given by a user is empty or holds values that are not non-negative integers."""


class InversionError(Genr8Error):
    """A rewrite system cannot be inverted to a genome in a universe; the message says which part."""


class ParseError(Genr8Error):
    """A rewrite system's text is malformed; ``line`` and ``column`` are 1-based."""

    def __init__(self, message: str, *, source: str = "<text>", line: int = 0, column: int = 0,
                 context: str = "") -> None:
        super().__init__(located(message, source, line, column))
        self.source = source
        self.line = line
        self.column = column
        self.context = context


class GrowthError(Genr8Error):
    """Growth cannot start or go on for a reason that is the input's fault."""


class StoreError(Genr8Error):
    """A run directory is missing, is not a run, or holds a corrupt file (named in the message)."""


class HistoryError(Genr8Error, ValueError):
    """A history request names something the run does not hold (an id, a criterion, a generation) or is
    malformed (an SQL statement); the message names the value at fault."""


class RunError(Genr8Error):
    """A run cannot start: it cannot be scheduled, or the Ray address answers nothing."""


def located(message: str, source: str, line: int = 0, column: int = 0) -> str:
    """Prefix ``message`` with ``source:line:column`` as compilers do (zero parts are left out)."""
    where = source
    if line:
        where += f":{line}"
        if column:
            where += f":{column}"
    return f"{where}: {message}"
