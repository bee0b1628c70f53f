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
from typing import TYPE_CHECKING

from genr8_dist.errors import GenomeError, UniverseError, located
from genr8_dist.grammar.compiler import MAX_MAX_DEPTH, CompiledGrammar, compile_grammar
from genr8_dist.grammar.hooks import RepairContext, hemls_repair, rule_predecessors
from genr8_dist.grammar.mapper import CompiledMapper, MapResult, _walk, compile_mapper
from genr8_dist.grammar.source import UniverseSource, load_modules

if TYPE_CHECKING:
    from lark import Lark

__all__ = ["MapResult", "Universe", "build_universe", "check_genome"]


class HookError(Exception):
    """A universe's hook raised: the genome being mapped fails at the ``map`` stage."""


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


def _rebuild(source: UniverseSource, origin: str, path: str) -> Universe:
    return build_universe(source, origin=origin, path=Path(path), check=False)


_BUILT: dict[tuple[str, str, str], Universe] = {}
_BUILT_LOCK = threading.Lock()
_SAMPLED: set[str] = set()   # digests whose derivations were parsed (check_sample passed)
SAMPLE_GENOMES = 48     # derivations parsed when a universe is loaded
SAMPLE_LENGTH = 200     # codons each


def build_universe(source: UniverseSource, *, origin: str | None = None, path: Path | None = None,
                   check: bool = True) -> Universe:
    """The universe ``source`` describes, built once per process (keyed by its digest).

    Its Python modules run only if this process consented to them (:mod:`genr8_dist.grammar.trust`),
    else :class:`UniverseError`. ``check`` also parses a sample of derivations
    (:meth:`Universe.check_sample`), so that a universe whose texts the phenotype cannot read fails now.
    """
    origin = origin if origin is not None else source.origin or "stored"
    key = (source.digest, source.name, origin)
    with _BUILT_LOCK:
        universe = _BUILT.get(key)
    if universe is None:   # built before: its hooks' names passed (parsing them costs ~6 ms a call)
        source.check_hook_names()
    modules = load_modules(source)   # refuses code this process has not consented to, cached or not
    if universe is None:
        path = path if path is not None else Path(source.where(source.grammar_file))
        universe = Universe(source.name, origin, path, source.grammar_text, modules.get("hooks"),
                            source=source)
        with _BUILT_LOCK:
            universe = _BUILT.setdefault(key, universe)
    if check and source.digest not in _SAMPLED:
        universe.check_sample()
        _SAMPLED.add(source.digest)
    return universe


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
                 hooks: ModuleType | None = None, *, source: UniverseSource | None = None) -> None:
        self.name = name
        self.origin = origin
        self.path = path
        self.source = source if source is not None else UniverseSource(name, ((Path(path).name, text),),
                                                                       origin=origin)
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
        self._parser: Lark | None = None

    def __reduce__(self) -> tuple[Callable[[UniverseSource, str, str], Universe],
                                  tuple[UniverseSource, str, str]]:
        """Pickle by source (the universe's files as text): compiled code is rebuilt where it lands,
        which needs no file of the plugin there (a Ray host on another machine)."""
        if self.hooks is not None and self.source.text("hooks.py") is None:
            raise UniverseError(f"universe '{self.name}': its hooks were given as a module, not as "
                                "source; build it with build_universe to send it elsewhere")
        return (_rebuild, (self.source, self.origin, str(self.path)))

    # ----------------------------------------------------------------------------- the phenotype

    def text_parser(self) -> Callable[[str], object] | None:
        """The parser of the universe's phenotype: the ``parse`` of its hooks' ``PHENOTYPE`` (``None``
        when that phenotype has none: its texts are then not checked at load), else the built-in
        surface phenotype's, HEMLS into a ``RewriteSystem`` (``genr8_dist.phenotype.phenotype_of``
        reads the same ``PHENOTYPE``; the phenotype layer sits above this one)."""
        phenotype = getattr(self.hooks, "PHENOTYPE", None) if self.hooks is not None else None
        if phenotype is None:
            from genr8_dist.hemls import parse

            return parse
        found: Callable[[str], object] | None = getattr(phenotype, "parse", None)
        return found

    def parse_system(self, text: str) -> object:
        """The phenotype's parser (``text_parser``) applied to a derived text; it raises for a text
        the phenotype cannot read. ``None`` when the phenotype has no parser."""
        parse = self.text_parser()
        return parse(text) if parse is not None else None

    def check_sample(self, max_depth: int = 5) -> None:
        """Parse ``SAMPLE_GENOMES`` derivations of seeded random genomes; the first one the phenotype's
        parser rejects is a :class:`UniverseError` naming the grammar literal it came from."""
        from genr8_dist.rng import stream

        if self.text_parser() is None:
            return
        gen = stream(0, "universe-check", self.source.digest[:16])
        genomes = gen.integers(0, 256, size=(SAMPLE_GENOMES, SAMPLE_LENGTH)).tolist()
        for genome in genomes:
            result = self.map(genome, max_depth=max_depth, max_wraps=2)
            if not result.valid or result.text is None:
                continue
            try:
                self.parse_system(result.text)
            except Exception as exc:  # the phenotype's parser: whatever it raises is the finding
                raise UniverseError(self._unreadable(result.text, exc)) from None

    def _unreadable(self, text: str, exc: Exception) -> str:
        line, column = getattr(exc, "line", 0) or 0, getattr(exc, "column", 0) or 0
        message = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        message = re.sub(r"^<[^>]*>(:\d+)*:\s*", "", message)
        token = ""
        if line and column:
            rows = text.splitlines()
            if line <= len(rows):
                m = re.match(r"\S+", rows[line - 1][column - 1:])
                token = m.group() if m else ""
        if token:
            from genr8_dist.grammar.compiler import find_literal

            at = find_literal(self.grammar.text, token)
            if at is not None:
                rule, lineno, col = at
                return located(f"the literal \"{token}\" ({rule}) derives text the phenotype's parser "
                               f"cannot read: {message}", str(self.path), lineno, col)
        first = text.splitlines()[line - 1] if line and line <= len(text.splitlines()) else ""
        shown = f" in the derived line '{first}'" if first else ""
        return located(f"a derivation of this universe cannot be read by the phenotype's parser{shown}: "
                       f"{message}", str(self.path))

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
            except HookError as exc:
                used = len(ext) - length_hint(it)
                return MapResult(None, False, str(exc), used, (used - 1) // n if used else 0)
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
        try:
            self._repair_hook(ctx)
        except StopIteration:
            raise
        except (Exception, SystemExit) as exc:  # a plugin's bug (sys.exit too): the genome fails at map
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
            raise HookError(f"hook repair of universe '{self.name}' raised {type(exc).__name__}"
                            + (f": {first}" if first else "")) from None
        if not isinstance(ctx.text, str):
            raise HookError(f"hook repair of universe '{self.name}' set ctx.text to a "
                            f"{type(ctx.text).__name__}, not a str")
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

    def parser(self) -> Lark:
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
