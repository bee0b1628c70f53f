"""A universe: a Lark grammar (plus optional hooks) that maps genomes to rewrite systems and back.

``Universe.map`` is Genr8's GE mapping (see :mod:`genr8_dist.grammar.mapper` for the exact rules);
``Universe.invert`` is the thesis's *regn8* (see :mod:`genr8_dist.grammar.inverse`). A universe is
compiled once, and its mapping function once per ``max_depth``; both are cached.
"""

from __future__ import annotations

import re
import threading
from array import array
from collections.abc import Callable, Iterable
from operator import length_hint
from pathlib import Path
from types import ModuleType
from typing import NamedTuple

from genr8_dist.errors import GenomeError, UniverseError
from genr8_dist.grammar.compiler import MAX_MAX_DEPTH, CompiledGrammar, compile_grammar
from genr8_dist.grammar.hooks import RepairContext, hemls_repair, load_hooks, rule_predecessors
from genr8_dist.grammar.mapper import CompiledMapper, _walk, compile_mapper

__all__ = ["MapResult", "Universe", "check_genome"]


class MapResult(NamedTuple):
    """The outcome of mapping one genome (an immutable record; a named tuple because it is made
    tens of thousands of times a second).

    ``text`` is the rewrite system (``None`` when invalid), ``reason`` says why a genome is invalid,
    ``codons_used`` counts codons read (wrapping included) and ``wraps`` how often the genome wrapped.
    """

    text: str | None
    valid: bool
    reason: str | None
    codons_used: int
    wraps: int


def check_genome(genome: Iterable[int]) -> list[int] | tuple[int, ...]:
    """``genome`` as a list or tuple of non-negative ``int``; :class:`GenomeError` otherwise."""
    if type(genome) is list or type(genome) is tuple:
        if genome:
            try:
                array("Q", genome)  # C-speed check: ints only, none negative
                return genome
            except (TypeError, OverflowError):
                pass
        seq = genome
    elif hasattr(genome, "dtype") and hasattr(genome, "tolist"):
        kind = getattr(genome.dtype, "kind", "?")
        if kind not in "iu" or getattr(genome, "ndim", 1) != 1:
            raise GenomeError(f"a genome is a 1-D array of integers, got an array of dtype {genome.dtype} "
                              f"with shape {getattr(genome, 'shape', '?')}")
        seq = genome.tolist()
    elif isinstance(genome, (list, tuple)):
        seq = genome
    elif isinstance(genome, (str, bytes)) or not isinstance(genome, Iterable):
        raise GenomeError(f"a genome is a sequence of non-negative integers, got {type(genome).__name__}")
    else:
        seq = list(genome)
    if not seq:
        raise GenomeError("the genome is empty: it needs at least one codon")
    if not set(map(type, seq)) <= {int}:
        fixed = []
        for i, value in enumerate(seq):
            if isinstance(value, bool) or not hasattr(value, "__index__"):
                raise GenomeError(f"codon {i} is {value!r}: codons are non-negative integers")
            fixed.append(value.__index__())
        seq = fixed
    if min(seq) < 0:
        i = next(i for i, v in enumerate(seq) if v < 0)
        raise GenomeError(f"codon {i} is {seq[i]}: codons are non-negative integers")
    return seq


def _rebuild(name: str, origin: str, path: str, text: str, hooks_dir: str | None) -> Universe:
    hooks = load_hooks(Path(hooks_dir)) if hooks_dir else None
    return Universe(name, origin, Path(path), text, hooks)


def _render(tokens: list[str]) -> str:
    """Tokens joined by single spaces, ``"\\n"`` tokens ending lines (``tokens`` loses a final one)."""
    if tokens and tokens[-1] == "\n":
        tokens.pop()
        return " ".join(tokens).replace(" \n ", "\n") + "\n"
    return " ".join(tokens).replace(" \n ", "\n")


class Universe:
    """One universe of rewrite systems: its grammar, where it came from, its hooks.

    ``name``: how it is looked up; ``origin``: ``"built-in"``, ``"plugin:<folder>"``, ``"path"`` or
    ``"entry point:<dist>"``; ``path``: its ``.lark`` file.
    """

    def __init__(self, name: str, origin: str, path: Path, text: str,
                 hooks: ModuleType | None = None) -> None:
        self.name = name
        self.origin = origin
        self.path = path
        self.grammar: CompiledGrammar = compile_grammar(text, str(path))
        self.description = self.grammar.description
        self.hooks = hooks
        self._mappers: dict[int, CompiledMapper] = {}
        self._lock = threading.Lock()
        self._repair_hook: Callable[[RepairContext], None] | None = None
        if hooks is not None and hasattr(hooks, "repair"):
            self._repair_hook = hooks.repair
        elif self.grammar.repair_rule is not None:
            self._repair_hook = hemls_repair
        if self._repair_hook is not None and self.grammar.repair_rule is None:
            raise UniverseError(f"{path}: hooks.py defines repair() but the universe names no repair "
                                "rule; add '//@ repair RULE'")
        templates = self.grammar.templates
        pred = [t for t in templates if t.terminal.startswith("PRED")] or list(templates)
        self._pred_template = pred[0] if pred else None
        self._pred_index = list(templates).index(pred[0]) if pred else 0
        self._has_pred = any(n[0] == "edge" and n[1] == "P" for alts in self.grammar.rules.values()
                             for alt in alts for n in _walk(alt))
        self._edge_res = [t.regex() for t in templates]
        self._labels: dict[str, int | None] = {}
        self._parser = None

    def __reduce__(self):
        """Pickle by source (name, origin, path, grammar text, hooks folder): compiled code is rebuilt."""
        hooks_dir = str(Path(self.hooks.__file__).parent) if self.hooks is not None else None
        return (_rebuild, (self.name, self.origin, str(self.path), self.grammar.text, hooks_dir))

    def __repr__(self) -> str:
        return f"Universe({self.name!r}, origin={self.origin!r}, path='{self.path}')"

    # ----------------------------------------------------------------------------- mapping

    def mapper(self, max_depth: int = 5) -> CompiledMapper:
        """The compiled mapping functions for ``max_depth`` (built once, then cached)."""
        m = self._mappers.get(max_depth)
        if m is None:
            if isinstance(max_depth, bool) or not isinstance(max_depth, int) \
                    or not 1 <= max_depth <= MAX_MAX_DEPTH:
                raise ValueError(f"max_depth must be an integer from 1 to {MAX_MAX_DEPTH}, got {max_depth!r}")
            with self._lock:
                m = self._mappers.get(max_depth)
                if m is None:
                    fast = self._repair_hook is hemls_repair and self._has_pred \
                        and self._pred_template is not None
                    m = compile_mapper(self.grammar, max_depth, self._pred_index if fast else None)
                    self._mappers[max_depth] = m
        return m

    def label_of(self, token: str) -> int | None:
        """The label of an edge token of this universe (``Edge3_i+1`` -> 3), ``None`` otherwise."""
        labels = self._labels
        if token in labels:
            return labels[token]
        label = None
        for regex in self._edge_res:
            m = regex.fullmatch(token)
            if m:
                label = int(m.group(1))
                break
        if len(labels) < 100_000:
            labels[token] = label
        return label

    def map(self, genome: Iterable[int], max_depth: int = 5, max_wraps: int = 2) -> MapResult:
        """Map ``genome`` to a rewrite system; invalid genomes come back ``valid=False`` with a reason.

        Raises :class:`GenomeError` only when ``genome`` is not a non-empty sequence of non-negative
        integers, and ``ValueError`` for a ``max_depth`` or ``max_wraps`` out of range.
        """
        seq = check_genome(genome)
        m = self._mappers.get(max_depth) or self.mapper(max_depth)
        if type(max_wraps) is not int or max_wraps < 0:
            raise ValueError(f"max_wraps must be a non-negative integer, got {max_wraps!r}")
        # Most genomes finish without wrapping: try the genome itself first, and only build the
        # wrapped copy (max_wraps + 1 repetitions) when the first pass runs out.
        n = len(seq)
        for attempt in (0, 1) if max_wraps else (0,):
            ext = seq * (max_wraps + 1) if attempt else seq
            it = iter(ext)
            nxt = it.__next__
            out: list[str] = []
            has: set[int] = set()
            try:
                if m.derive_hemls is not None:
                    _count, new = m.derive_hemls(nxt, out, has)
                    text = _render(out)
                    if new:
                        end = text.find("\n", text.rfind("->")) + 1 or len(text)
                        text = f"{text[:end]}{chr(10).join(new)}\n{text[end:]}"
                else:
                    count = m.derive(nxt, out, has.add)
                    text = _render(out)
                    if self._repair_hook is not None:
                        text = self._run_repair(m, nxt, out, text, count, has)
            except StopIteration:
                continue
            used = len(ext) - length_hint(it)
            return MapResult(text, True, None, used, (used - 1) // n if used else 0)
        return MapResult(None, False,
                         f"genome exhausted: {n} codons read {max_wraps + 1} times "
                         f"(max_wraps={max_wraps}) without finishing the derivation",
                         n * (max_wraps + 1), max_wraps)

    def _run_repair(self, m: CompiledMapper, nxt: Callable[[], int], out: list[str], text: str,
                    count: int, has: set[int]) -> str:
        """Run the repair hook over ``text``; returns the repaired text."""
        if not self._has_pred:
            has = rule_predecessors(text, self.label_of)
        if self._repair_hook is hemls_repair and self._pred_template is not None:
            return self._hemls_repair(m, nxt, out, text, count, has)
        occurring = set(range(2, count))
        occurring.update(k for k in (0, 1) if any(table[k] in out for table in m.distinct))
        acc: list[str] = []
        assert m.repair is not None and self._repair_hook is not None  # a universe that repairs
        grow_one = m.repair(nxt, acc, count)

        def expand() -> list[str]:
            start = len(acc)
            grow_one()
            return acc[start:]

        get = m.labels.get

        def labels_in(tokens: list[str]) -> set[int]:
            return {label for label in map(get, tokens) if label is not None}

        template = self._pred_template
        ctx = RepairContext(text=text, expand=expand, occurring=occurring, has_rule=has,
                            label_of=self.label_of, edge=template.text if template else str,
                            count=count, labels_in=labels_in)
        self._repair_hook(ctx)
        return ctx.text

    def _hemls_repair(self, m: CompiledMapper, nxt: Callable[[], int], out: list[str], text: str,
                      count: int, has: set[int]) -> str:
        """:func:`~genr8_dist.grammar.hooks.hemls_repair`, inlined for speed (same result)."""
        missing = {k for k in range(count) if k not in has}
        for k in (0, 1):
            if k in missing and not any(table[k] in out for table in m.distinct):
                missing.discard(k)  # labels 0 and 1 exist from the start but may never occur
        if not missing:
            return text
        arrow = text.rfind("->")
        if arrow < 0:
            return text
        end = text.find("\n", arrow)
        end = len(text) if end < 0 else end + 1
        get = m.labels.get
        acc: list[str] = []
        assert m.repair is not None  # a universe that repairs
        expand = m.repair(nxt, acc, count)
        edges = m.tables[self._pred_index]
        new = []
        while missing:
            label = min(missing)
            missing.discard(label)
            has.add(label)
            start = len(acc)
            expand()
            successor = acc[start:]
            new.append(" ".join([edges[label], "->", *successor]))
            for lab in set(map(get, successor)):
                if lab is not None and lab not in has:
                    missing.add(lab)
        return f"{text[:end]}{chr(10).join(new)}\n{text[end:]}"

    # ----------------------------------------------------------------------------- inverse

    def parser(self):
        """A Lark Earley parser for this universe's rewrite systems (built once)."""
        if self._parser is None:
            from lark import Lark

            text = self.grammar.text
            if not re.search(r"^%ignore", text, re.MULTILINE):
                text += '\n%ignore /[ \\t]+/\n'
            self._parser = Lark(text, parser="earley", lexer="dynamic", keep_all_tokens=True,
                                propagate_positions=False)
        return self._parser

    def invert(self, text: str, max_depth: int = 5) -> tuple[int, ...]:
        """A genome that maps to ``text`` (labels renamed to birth order); :class:`InversionError` else."""
        from genr8_dist.grammar.inverse import invert

        return invert(self, text, max_depth=max_depth)
