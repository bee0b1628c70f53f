"""Hornby & Pollack's variation (GECCO 2001, sections 2.4 to 2.6): random P0L-systems and command
strings, and the structural mutation and recombination both encodings used.

Free of genr8_dist: every function takes a ``numpy.random.Generator`` and texts of the tables
universes (``voxels.parse`` reads them; ``write`` writes them back, compactly), so the same seed
gives the same texts. The engine calls these through ``hooks.VARIATION`` (``genr8_dist.evolution.
variation``).

The generative genome (``Generative``): an axiom ``P0(a, b)`` with its number of derivation steps,
and ``PRODUCTIONS`` (20) productions of two parameters with 1 to 3 condition-successor pairs each.

* Initialisation (2.4): every successor a random string of 3 to 8 build commands in blocks of 1 to 3
  commands, each block enclosed in ``[ ]``, in ``{ }(n)`` or in nothing (a third each); a build
  command is one of table 1's eight or, with probability ``CALL_SHARE``, a call ``Pk(x op y, x op y)``.
  Conditions ``n0 > c`` / ``n1 > c`` with ``c`` in ``LIMITS_AT_START``; command and equation constants
  in 1..5; the axiom's parameters in 1..10, its steps in ``ITERATIONS_AT_START``.
* Mutation (2.5) of one production drawn from those the axiom reaches: replace a command by another;
  perturb a command's constant by +-1; change a call's parameter equation; insert a block of 1 to 3
  commands; delete 1 to 3 items; change a condition (its parameter, or its limit by +-1 to +-3);
  encapsulate 1 to 3 items into an unused production (which gets the mutated production's conditions,
  each with the encapsulated items as its successor) called as ``Pk(n0, n1)``. One mutation in
  ``GLOBAL_SHARE`` changes the axiom instead: its steps or one of its parameters by +-1.
* Recombination (3.6): a copy of the first parent with a small part of the second put in: one
  condition-successor pair replaced by one of the second parent's, just a successor replaced, a
  sub-sequence inserted, or a sub-sequence replaced by one of the second parent's.

The direct genome (``Direct``, the paper's non-generative encoding): one string of build commands,
without block replication and without calls, 4 to 104 commands at first (blocks of 1 to 3, each in
``[ ]`` or not), at most ``MAX_DIRECT`` (20,000) commands. The same operators where they apply:
replace, perturb, insert, delete; recombination inserts or replaces a sub-sequence. A child that
would pass ``MAX_DIRECT`` commands loses its last items until it does not.

Ranges every operator keeps: constants 0..``MAX_CONSTANT``, limits ``-MAX_LIMIT..MAX_LIMIT``, steps
1..``voxels.MAX_ITERATIONS``, axiom parameters 0..``MAX_CONSTANT`` (the paper's table 4.d: 17 steps,
limits 22 and -10, axiom ``P0(4, 10)``, all reachable).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from . import voxels

PRODUCTIONS = 20
MAX_PAIRS = 3
CALL_SHARE = 0.25
GLOBAL_SHARE = 0.1
ITERATIONS_AT_START = (1, 2)
LIMITS_AT_START = (-5, 10)
MAX_CONSTANT = 40
MAX_LIMIT = 30
MAX_DIRECT = voxels.MAX_COMMANDS
DIRECT_AT_START = (4, 104)

SYMBOLS = tuple(voxels.COMMANDS)   # f b ^ v < > / \
OPS = ("+", "-", "*", "/")


# --------------------------------------------------------------------------------------------------
# Writing a system back as text (what voxels.parse reads: write(parse(t)) == write(parse(write(...)))).


def _num(v: float) -> str:
    text = f"{float(v):.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _expr(e: tuple) -> str:
    if e[0] == "k":
        return _num(e[1])
    if e[0] == "p":
        return f"n{e[1]}"
    return f"{_expr(e[2])}{e[1]}{_expr(e[3])}"


def _arg(value: Any) -> str:
    """A command's argument: an expression, or a plain number (a direct string's, as parsed)."""
    return _expr(value) if isinstance(value, tuple) else _num(value)


def write_items(items: Any) -> str:
    """Successor items (or a direct string's) in compact text: ``f(3) [^(1) P2(n0-1,n1)] {b(n0)}(4)``."""
    out = []
    for item in items:
        kind = item[0]
        if kind == "c":
            out.append(f"{item[1]}({_arg(item[2])})")
        elif kind == "call":
            out.append(f"{item[1]}({','.join(_arg(e) for e in item[2])})")
        elif kind == "[":
            out.append(f"[{write_items(item[1])}]")
        else:
            out.append(f"{{{write_items(item[2])}}}({_arg(item[1])})")
    return " ".join(out)


def write(system: voxels.System) -> str:
    """The text of ``system``: a P0L-system (axiom line, then one production per line) or, with no
    productions and no steps, a direct command string."""
    if not system.productions and not system.iterations and not any(
            item[0] == "call" for item in system.axiom):
        return write_items(system.axiom) + "\n"
    (head,) = system.axiom
    lines = [f"{head[1]}({','.join(_arg(e) for e in head[2])}) iterations {system.iterations}"]
    lines += [_production_line(production) for production in system.productions.values()]
    return "\n".join(lines) + "\n"


def _production_line(production: voxels.Production) -> str:
    """One production's line (cached when it is all tuples, as the operators' children are: a child
    shares all but one or two of its parent's lines; ``voxels.parse`` leaves lists inside)."""
    try:
        return _cached_line(production)
    except TypeError:
        return _line(production)


@lru_cache(maxsize=8192)
def _cached_line(production: voxels.Production) -> str:
    return _line(production)


def _line(production: voxels.Production) -> str:
    pairs = " | ".join(f"{production.params[i]}>{_num(limit)} -> {write_items(items)}".rstrip()
                       for i, limit, items in production.pairs)
    return f"{production.name}({','.join(production.params)}): {pairs}"


# --------------------------------------------------------------------------------------------------
# Mutable copies: lists in place of tuples, so an operator edits one place of a copy.


def _thaw(items: Any) -> list:
    out: list = []
    for item in items:
        if item[0] == "[":
            out.append(["[", _thaw(item[1])])
        elif item[0] == "{":
            out.append(["{", item[1], _thaw(item[2])])
        else:
            out.append(list(item))
    return out


def _freeze(items: list) -> tuple:
    out = []
    for item in items:
        if item[0] == "[":
            out.append(("[", _freeze(item[1])))
        elif item[0] == "{":
            out.append(("{", item[1], _freeze(item[2])))
        elif item[0] == "call":
            out.append(("call", item[1], tuple(item[2])))
        else:
            out.append(tuple(item))
    return tuple(out)


def _lists(items: list) -> list[list]:
    """``items`` and every bracket's and block's body inside it, depth first (where edits go)."""
    found = [items]
    for item in items:
        if item[0] == "[":
            found += _lists(item[1])
        elif item[0] == "{":
            found += _lists(item[2])
    return found


def _count(items: Any) -> int:
    """Items in ``items``, brackets' and blocks' bodies included (a direct string's commands)."""
    n = 0
    for item in items:
        n += 1
        if item[0] == "[":
            n += _count(item[1]) - 1
        elif item[0] == "{":
            n += _count(item[2])
    return n


def _pick(rng: np.random.Generator, seq: list) -> Any:
    return seq[int(rng.integers(0, len(seq)))]


def _span(rng: np.random.Generator, n: int) -> tuple[int, int]:
    """A random slice ``[start, stop)`` of 1 to 3 of ``n`` items (``n`` >= 1)."""
    length = int(rng.integers(1, min(3, n) + 1))
    start = int(rng.integers(0, n - length + 1))
    return start, start + length


def _clip(v: float, low: float, high: float) -> float:
    return float(min(high, max(low, v)))


# --------------------------------------------------------------------------------------------------
# Random pieces (section 2.4).


class _Maker:
    """Random expressions, commands and blocks for one encoding (``generative``: calls, parameters
    and block replication allowed; else table 1's commands with constants only)."""

    def __init__(self, generative: bool) -> None:
        self.generative = generative

    def constant(self, rng: np.random.Generator) -> tuple:
        return ("k", float(rng.integers(1, 6)))

    def argument(self, rng: np.random.Generator) -> Any:
        if not self.generative:
            return float(rng.integers(1, 6))
        return ("p", int(rng.integers(0, 2))) if rng.random() < 0.3 else self.constant(rng)

    def term(self, rng: np.random.Generator) -> tuple:
        return ("p", int(rng.integers(0, 2))) if rng.random() < 0.5 else self.constant(rng)

    def equation(self, rng: np.random.Generator) -> tuple:
        return ("op", _pick(rng, list(OPS)), self.term(rng), self.term(rng))

    def command(self, rng: np.random.Generator) -> list:
        if self.generative and rng.random() < CALL_SHARE:
            return ["call", f"P{int(rng.integers(0, PRODUCTIONS))}", [self.equation(rng), self.equation(rng)]]
        return ["c", _pick(rng, list(SYMBOLS)), self.argument(rng)]

    def block(self, rng: np.random.Generator, size: int) -> list:
        """``size`` commands enclosed in ``[ ]``, in ``{ }(n)`` (generative only) or in nothing."""
        commands = [self.command(rng) for _ in range(size)]
        kind = int(rng.integers(0, 3 if self.generative else 2))
        if kind == 0:
            return commands
        if kind == 1:
            return [["[", commands]]
        return [["{", self.argument(rng), commands]]

    def string(self, rng: np.random.Generator, low: int, high: int) -> list:
        """A random string of ``low`` to ``high`` commands in blocks of 1 to 3."""
        want = int(rng.integers(low, high + 1))
        items: list = []
        while want > 0:
            size = min(want, int(rng.integers(1, 4)))
            items += self.block(rng, size)
            want -= size
        return items


# --------------------------------------------------------------------------------------------------
# The operators shared by both encodings (on one list of items).


def _replace_command(rng: np.random.Generator, items: list, maker: _Maker) -> bool:
    places = [(lst, i) for lst in _lists(items) for i, it in enumerate(lst) if it[0] in ("c", "call")]
    if not places:
        return False
    lst, i = _pick(rng, places)
    new = maker.command(rng)
    if new[0] == "c" and lst[i][0] == "c":   # another command: keep the argument, change the symbol
        new[2] = lst[i][2]
    lst[i] = new
    return True


def _perturb(rng: np.random.Generator, items: list, maker: _Maker) -> bool:
    places = [(it, 2 if it[0] == "c" else 1) for lst in _lists(items) for it in lst if it[0] in ("c", "{")]
    if not places:
        return False
    item, slot = _pick(rng, places)
    step = 1.0 if rng.random() < 0.5 else -1.0
    value = item[slot]
    if isinstance(value, tuple) and value[0] == "k":
        item[slot] = ("k", _clip(value[1] + step, 0, MAX_CONSTANT))
    elif isinstance(value, tuple):   # a parameter (or an equation): a constant in its place
        item[slot] = maker.constant(rng)
    else:
        item[slot] = _clip(value + step, 0, MAX_CONSTANT)
    return True


def _insert(rng: np.random.Generator, items: list, maker: _Maker) -> bool:
    lst = _pick(rng, _lists(items))
    at = int(rng.integers(0, len(lst) + 1))
    lst[at:at] = maker.block(rng, int(rng.integers(1, 4)))
    return True


def _delete(rng: np.random.Generator, items: list, maker: _Maker) -> bool:
    lists = [lst for lst in _lists(items) if lst]
    if not lists:
        return False
    lst = _pick(rng, lists)
    start, stop = _span(rng, len(lst))
    del lst[start:stop]
    return True


def _sub_sequence(rng: np.random.Generator, items: list) -> list:
    lists = [lst for lst in _lists(items) if lst]
    if not lists:
        return []
    lst = _pick(rng, lists)
    start, stop = _span(rng, len(lst))
    return _thaw(_freeze(lst[start:stop]))


def _put(rng: np.random.Generator, items: list, piece: list, replace: bool) -> bool:
    """``piece`` inserted at a random place of ``items``, or in place of a random 1 to 3 items."""
    if not piece:
        return False
    lists = [lst for lst in _lists(items) if lst or not replace]
    if not lists:
        return False
    lst = _pick(rng, lists)
    if replace:
        start, stop = _span(rng, len(lst))
    else:
        start = stop = int(rng.integers(0, len(lst) + 1))
    lst[start:stop] = piece
    return True


# --------------------------------------------------------------------------------------------------
# The direct encoding.


class Direct:
    """The paper's non-generative genome: one command string (no block replication, no calls)."""

    def __init__(self) -> None:
        self.maker = _Maker(generative=False)

    def founder(self, rng: np.random.Generator) -> str:
        return write_items(_freeze(self.maker.string(rng, *DIRECT_AT_START))) + "\n"

    def _items(self, text: str) -> list:
        return _thaw(voxels.parse(text).axiom)

    def _done(self, items: list) -> str:
        while _count(items) > MAX_DIRECT and items:
            items.pop()
        if not items:
            items.append(["c", "f", 1.0])
        return write_items(_freeze(items)) + "\n"

    def mutate(self, rng: np.random.Generator, text: str) -> str:
        items = self._items(text)
        operators = (_replace_command, _perturb, _insert, _delete)
        for _ in range(8):   # an operator with nothing to work on (delete of nothing) draws again
            if _pick(rng, list(operators))(rng, items, self.maker):
                break
        return self._done(items)

    def recombine(self, rng: np.random.Generator, text: str, other: str) -> str:
        items = self._items(text)
        piece = _sub_sequence(rng, self._items(other))
        _put(rng, items, piece, replace=bool(rng.random() < 0.5))
        return self._done(items)


# --------------------------------------------------------------------------------------------------
# The generative encoding.


def _two(values: list, pad: Any) -> list:
    """``values`` as the paper's two parameters: a third and later dropped, a missing one ``pad``."""
    return [*values, pad, pad][:2]


class _Rules:
    """A mutable P0L-system: axiom ``[name, [a, b]]``, steps, productions ``name -> [[param, limit,
    items], ...]`` in P0..P19 order (a production with no pair is left out of the text). Every
    production has the paper's two parameters: a text written with one (section 2.2's example) is
    read with a second that nothing uses, every call and the axiom given a 0 for it."""

    def __init__(self, system: voxels.System) -> None:
        (head,) = system.axiom
        self.axiom = [head[1], _two([float(v) for v in head[2]], 0.0)]
        self.iterations = system.iterations
        self.productions: dict[str, list[list]] = {f"P{k}": [] for k in range(PRODUCTIONS)}
        for name, production in system.productions.items():
            pairs = [[i, float(limit), _thaw(items)] for i, limit, items in production.pairs]
            for _, _, items in pairs:
                for lst in _lists(items):
                    for item in lst:
                        if item[0] == "call":
                            item[2] = _two(list(item[2]), ("k", 0.0))
            self.productions[name] = pairs

    def used(self) -> list[str]:
        """The productions the axiom reaches through calls (in P0..P19 order)."""
        seen, todo = {self.axiom[0]}, [self.axiom[0]]
        while todo:
            for _, _, items in self.productions.get(todo.pop(), []):
                for lst in _lists(items):
                    for item in lst:
                        if item[0] == "call" and item[1] not in seen:
                            seen.add(item[1])
                            todo.append(item[1])
        return [name for name in self.productions if name in seen and self.productions[name]]

    def text(self) -> str:
        productions = {name: voxels.Production(name, ("n0", "n1"),
                                               tuple((i, limit, _freeze(items)) for i, limit, items in pairs))
                       for name, pairs in self.productions.items() if pairs}
        axiom = (("call", self.axiom[0], tuple(self.axiom[1])),)
        return write(voxels.System(axiom, self.iterations, productions))


class Generative:
    """The paper's generative genome: a P0L-system of 20 productions, its axiom and its steps."""

    def __init__(self) -> None:
        self.maker = _Maker(generative=True)

    def _pair(self, rng: np.random.Generator) -> list:
        return [int(rng.integers(0, 2)), float(rng.integers(LIMITS_AT_START[0], LIMITS_AT_START[1] + 1)),
                self.maker.string(rng, 3, 8)]

    def founder(self, rng: np.random.Generator) -> str:
        axiom = (("call", "P0", (float(rng.integers(1, 11)), float(rng.integers(1, 11)))),)
        rules = _Rules(voxels.System(axiom, int(rng.integers(*ITERATIONS_AT_START, endpoint=True)), {}))
        for name in rules.productions:
            rules.productions[name] = [self._pair(rng) for _ in range(int(rng.integers(1, MAX_PAIRS + 1)))]
        return rules.text()

    def mutate(self, rng: np.random.Generator, text: str) -> str:
        rules = _Rules(voxels.parse(text))
        used = rules.used()
        if not used or rng.random() < GLOBAL_SHARE:
            self._mutate_axiom(rng, rules)
            return rules.text()
        name = _pick(rng, used)
        pairs = rules.productions[name]
        operators = (self._replace, self._perturb, self._equation, self._insert, self._delete,
                     self._condition, self._encapsulate)
        for _ in range(8):
            if _pick(rng, list(operators))(rng, rules, name, pairs):
                break
        return rules.text()

    @staticmethod
    def _mutate_axiom(rng: np.random.Generator, rules: _Rules) -> None:
        step = 1 if rng.random() < 0.5 else -1
        if rng.random() < 0.5:
            rules.iterations = int(_clip(rules.iterations + step, 1, voxels.MAX_ITERATIONS))
        else:
            k = int(rng.integers(0, 2))
            rules.axiom[1][k] = _clip(rules.axiom[1][k] + step, 0, MAX_CONSTANT)

    def _body(self, rng: np.random.Generator, pairs: list) -> list:
        return _pick(rng, pairs)[2]

    def _replace(self, rng, rules, name, pairs) -> bool:
        return _replace_command(rng, self._body(rng, pairs), self.maker)

    def _perturb(self, rng, rules, name, pairs) -> bool:
        return _perturb(rng, self._body(rng, pairs), self.maker)

    def _insert(self, rng, rules, name, pairs) -> bool:
        return _insert(rng, self._body(rng, pairs), self.maker)

    def _delete(self, rng, rules, name, pairs) -> bool:
        return _delete(rng, self._body(rng, pairs), self.maker)

    def _equation(self, rng, rules, name, pairs) -> bool:
        calls = [it for lst in _lists(self._body(rng, pairs)) for it in lst if it[0] == "call"]
        if not calls:
            return False
        call = _pick(rng, calls)
        k = int(rng.integers(0, len(call[2])))
        call[2] = list(call[2])
        call[2][k] = self.maker.equation(rng)
        return True

    def _condition(self, rng, rules, name, pairs) -> bool:
        pair = _pick(rng, pairs)
        if rng.random() < 0.25:
            pair[0] = 1 - pair[0]
        else:
            step = float(rng.integers(1, 4)) * (1 if rng.random() < 0.5 else -1)
            pair[1] = _clip(pair[1] + step, -MAX_LIMIT, MAX_LIMIT)
        return True

    def _encapsulate(self, rng, rules, name, pairs) -> bool:
        used = set(rules.used())
        free = [n for n in rules.productions if n not in used]
        body = self._body(rng, pairs)
        lists = [lst for lst in _lists(body) if lst]
        if not free or not lists:
            return False
        new = _pick(rng, free)
        lst = _pick(rng, lists)
        start, stop = _span(rng, len(lst))
        block = lst[start:stop]
        lst[start:stop] = [["call", new, [("p", 0), ("p", 1)]]]
        rules.productions[new] = [[i, limit, _thaw(_freeze(block))] for i, limit, _ in pairs]
        return True

    def recombine(self, rng: np.random.Generator, text: str, other: str) -> str:
        rules, donor = _Rules(voxels.parse(text)), _Rules(voxels.parse(other))
        used = rules.used() or [rules.axiom[0]]
        name = _pick(rng, used)
        pairs = rules.productions[name]
        given = donor.productions.get(name) or donor.productions[_pick(rng, donor.used() or ["P0"])]
        if not pairs or not given:
            return rules.text()
        source = _pick(rng, given)
        way = int(rng.integers(0, 4))
        k = int(rng.integers(0, len(pairs)))
        if way == 0:     # an entire condition-successor pair
            pairs[k] = [source[0], source[1], _thaw(_freeze(source[2]))]
        elif way == 1:   # just a successor
            pairs[k][2] = _thaw(_freeze(source[2]))
        else:            # a sub-sequence inserted, or in place of one
            piece = _sub_sequence(rng, source[2])
            if not _put(rng, pairs[k][2], piece, replace=way == 3):
                pairs[k][2] = _thaw(_freeze(source[2]))
        return rules.text()


GENERATIVE = Generative()
DIRECT = Direct()

__all__ = ["DIRECT", "GENERATIVE", "MAX_DIRECT", "PRODUCTIONS", "Direct", "Generative", "write",
           "write_items"]
