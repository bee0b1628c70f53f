"""Hornby & Pollack's evolved tables (GECCO 2001): P0L-systems that build voxel structures.

A *text* of the ``tables`` universe is a parametric 0L-system (section 2.2), one production per line::

    P0 ( 4 , 10 ) iterations 12                      the axiom and the number of derivation steps
    P0 ( n0 , n1 ) : n1 > 3 -> P1 ( n0 - 4 , n0 / 2 ) v ( 1 ) { P2 ( n1 , 2 ) } ( 4 ) | n0 > 2 -> [ b ( 5 ) ]
    P1 ( n0 , n1 ) : n0 > 0 -> ...

A production has a predecessor (a name and its formal parameters), then condition-successor pairs
separated by ``|``; a condition compares one parameter with a constant (``n1 > 3``). In a derivation
step every call module ``Pk(a, b)`` is replaced, in parallel, by the successor of the first pair of
``Pk`` whose condition holds; when none holds (or ``Pk`` has no production) it is replaced by nothing,
as in the paper's example (``P0(1)`` vanishes) and its table 4.d (``P16``). A successor holds the
build commands of table 1, calls, push/pop brackets ``[ ]`` and block replication ``{ ... } ( n )``.
Parameters to commands are a constant or a parameter; parameters to calls are equations
``x op y`` (``op`` one of ``+ - * /``, ``x`` and ``y`` a parameter or a constant). Division by zero
gives 0 and every computed value is clamped to [-1e6, 1e6], so a derivation never fails on arithmetic.

A text of the ``tables_direct`` universe (the paper's non-generative baseline) is one line of build
commands and brackets, without block replication and without productions.

Development, then: the axiom is rewritten ``iterations`` times (stopping early, flagged ``capped``,
when the word would pass ``MAX_MODULES`` modules), leftover calls are dropped, and the command string
drives a LOGO-style turtle on a 40 x 40 x 40 voxel grid (section 2.1):

=====  ===================  =====================================================================
``f``  forward(n)           move ``n`` cells along the heading (the turtle's X axis), filling each
``b``  backward(n)          move ``n`` cells against the heading, filling each
``^``  up(n)                rotate ``n`` x 90 degrees about the turtle's Z axis (``v``: -90)
``<``  left(n)              rotate ``n`` x 90 degrees about the turtle's Y axis (``>``: -90)
``/``  clockwise(n)         rotate ``n`` x 90 degrees about the turtle's X axis (``\\``: -90)
``[``  ``]``                push / pop the turtle's position and orientation
``{ }(n)``                  repeat the enclosed block ``n`` times
=====  ===================  =====================================================================

Grid cells are ``(x, y, z)`` with ``y`` up. The turtle starts in the filled cell (20, 0, 20) on the
ground, heading +x with its Y axis up; ``n`` is truncated to an integer (``forward(4.5)`` moves 4;
a negative move goes the other way; rotations are ``n mod 4`` quarter turns); a move that would leave
the grid stops at its edge. The turtle only ever enters a cell next to the one it stands in and fills
every cell it enters, so the voxels always form one face-connected structure. At most
``MAX_COMMANDS`` commands run (the paper's direct encoding allows 20,000); later ones are skipped and
the table is flagged ``capped``.

Criteria (section 3), with ``Y_max`` the highest filled layer: ``height = Y_max``, ``surface`` = the
voxels in layer ``Y_max``, ``stability`` = the sum over the layers below ``Y_max`` of the area of the
convex hull of the layer's voxels (unit squares), ``excess`` = the voxels not in layer ``Y_max``;
``fitness = height * surface * stability / excess`` (0 when ``excess`` is 0), to be maximised.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

GRID = 40
START = (20, 0, 20)
MAX_MODULES = 50_000
MAX_COMMANDS = 20_000
MAX_ITERATIONS = 30
LIMIT = 1e6

COMMANDS = {"f": "forward", "b": "backward", "^": "up", "v": "down", "<": "left", ">": "right",
            "/": "clockwise", "\\": "counter-clockwise"}
CRITERIA = ("height", "surface", "stability", "excess", "voxels")


class TablesError(ValueError):
    """A text that is not a P0L-system or command string of the tables universes."""


# --------------------------------------------------------------------------------------------------
# Parsing. Expressions are ("k", value) constants, ("p", i) parameters and ("op", op, a, b) equations.
# Successor items: ("c", symbol, expr), ("call", name, (expr, ...)), ("[", items), ("{", expr, items).
# A word (after substitution) has the same shape with plain floats in place of expressions.

_TOKEN = re.compile(r"\s*(->|\d+(?:\.\d*)?|\.\d+|[A-Za-z_]\w*|[()\[\]{},:|+\-*/\\^<>]|\S)")
_PUNCTUATION = frozenset("()[]{},:|+-*/\\^<>_")


def _tokens(line: str, lineno: int) -> list[str]:
    out = _TOKEN.findall(line)
    for token in out:
        if len(token) == 1 and not token.isalnum() and token not in _PUNCTUATION:
            col = _columns(line)[out.index(token)]
            raise TablesError(f"line {lineno}, column {col}: unexpected character {token!r}")
    return out


def _columns(line: str) -> list[int]:
    """The column (from 1) of each token of ``line``: only an error message needs them."""
    return [m.start(1) + 1 for m in _TOKEN.finditer(line)]


class _Line:
    """A recursive-descent reader over one line's tokens."""

    def __init__(self, line: str, lineno: int, params: tuple[str, ...] = ()) -> None:
        self.line = line
        self.toks = _tokens(line, lineno)
        self.n = len(self.toks)
        self.i = 0
        self.lineno = lineno
        self.params = params

    def peek(self) -> str | None:
        return self.toks[self.i] if self.i < self.n else None

    def fail(self, what: str) -> TablesError:
        if self.i < self.n:
            tok, col = self.toks[self.i], _columns(self.line)[self.i]
            return TablesError(f"line {self.lineno}, column {col}: expected {what}, got {tok!r}")
        return TablesError(f"line {self.lineno}: expected {what} at the end of the line")

    def take(self, want: str | None = None) -> str:
        tok = self.peek()
        if tok is None or (want is not None and tok != want):
            raise self.fail(repr(want) if want else "more")
        self.i += 1
        return tok

    def done(self) -> bool:
        return self.i >= self.n

    def number(self) -> float:
        sign = -1.0 if self.peek() == "-" else 1.0
        if sign < 0:
            self.i += 1
        tok = self.peek()
        if tok is None or not re.fullmatch(r"\d+(?:\.\d*)?|\.\d+", tok):
            raise self.fail("a number")
        self.i += 1
        return sign * float(tok)

    def term(self) -> tuple:
        tok = self.peek()
        if tok in self.params:
            self.i += 1
            return ("p", self.params.index(tok))
        return ("k", self.number())

    def expr(self) -> tuple:
        left = self.term()
        op = self.peek()
        follows = self.toks[self.i + 1] if self.i + 1 < self.n else None
        if op in ("+", "-", "*", "/") and follows not in (None, ",", ")"):
            self.i += 1
            return ("op", op, left, self.term())
        return left

    def args(self) -> tuple:
        self.take("(")
        out = [self.expr()]
        while self.peek() == ",":
            self.i += 1
            out.append(self.expr())
        self.take(")")
        return tuple(out)

    def items(self, close: str | None, direct: bool) -> list:
        out: list = []
        while True:
            tok = self.peek()
            if tok == close or (close is None and (tok is None or tok == "|")):
                return out
            if tok is None:
                raise self.fail(repr(close))
            if tok in COMMANDS:
                self.i += 1
                (arg,) = self._one(tok)
                out.append(("c", tok, arg))
            elif tok == "[":
                self.i += 1
                body = self.items("]", direct)
                self.take("]")
                out.append(("[", body))
            elif tok == "{" and not direct:
                self.i += 1
                body = self.items("}", direct)
                self.take("}")
                (count,) = self._one("}")
                out.append(("{", count, body))
            elif re.fullmatch(r"P\d+", tok) and not direct:
                self.i += 1
                out.append(("call", tok, self.args()))
            else:
                raise self.fail("a build command (f b ^ v < > / \\)" + (", '[' or ']'" if direct else
                                                                         ", a call Pk, '[', '{'"))

    def _one(self, owner: str) -> tuple:
        args = self.args()
        if len(args) != 1:
            raise TablesError(f"line {self.lineno}: {owner} takes one argument, got {len(args)}")
        return args


@dataclass(frozen=True)
class Production:
    """``name(params) : param > limit -> successor | ...``: pairs of (parameter index, limit, items)."""

    name: str
    params: tuple[str, ...]
    pairs: tuple[tuple[int, float, tuple], ...]


@dataclass(frozen=True)
class System:
    """A P0L-system (``productions`` empty for a direct command string): axiom, iterations, rules."""

    axiom: tuple
    iterations: int
    productions: dict[str, Production]


@lru_cache(maxsize=256)
def parse(text: str) -> System:
    """Read a tables text: a P0L-system (its first line holds ``iterations``) or a command string."""
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise TablesError("the text is empty: no axiom and no commands")
    first_no, first = lines[0]
    if "iterations" not in first.split():
        if len(lines) > 1:
            raise TablesError(f"line {lines[1][0]}: a command string (no 'iterations' on its first "
                              "line) is one line")
        reader = _Line(first, first_no)
        items = reader.items(None, direct=True)
        if not reader.done():
            raise reader.fail("a build command")
        return System(_substitute(items, ()), 0, {})
    head = _Line(first, first_no)
    name = head.take()
    if not re.fullmatch(r"P\d+", name):
        raise TablesError(f"line {first_no}: the axiom is a call such as 'P0 ( 4 , 10 )', got {name!r}")
    args = tuple(_value(e, ()) for e in head.args())
    head.take("iterations")
    iterations = head.number()
    if not head.done():
        raise head.fail("the end of the axiom line")
    if iterations != int(iterations) or not 0 <= iterations <= MAX_ITERATIONS:
        raise TablesError(f"line {first_no}: iterations must be an integer from 0 to {MAX_ITERATIONS}, "
                          f"got {iterations:g}")
    productions: dict[str, Production] = {}
    for lineno, line in lines[1:]:
        production = _production(line, lineno)
        if production.name in productions:
            raise TablesError(f"line {lineno}: production {production.name} is defined twice")
        productions[production.name] = production
    return System((("call", name, args),), int(iterations), productions)


@lru_cache(maxsize=8192)
def _production(line: str, lineno: int) -> Production:
    """One production line (cached: a child of mutation or recombination shares all but one or two
    of its parent's lines, so most of a new text is read once)."""
    reader = _Line(line, lineno)
    pname = reader.take()
    if not re.fullmatch(r"P\d+", pname):
        raise TablesError(f"line {lineno}: a production starts with its name Pk, got {pname!r}")
    reader.take("(")
    params = [reader.take()]
    while reader.peek() == ",":
        reader.i += 1
        params.append(reader.take())
    reader.take(")")
    if any(not re.fullmatch(r"n\d+", p) for p in params) or len(set(params)) != len(params):
        raise TablesError(f"line {lineno}: formal parameters are distinct names n0, n1, ..., got "
                          f"{', '.join(params)}")
    reader.params = tuple(params)
    reader.take(":")
    pairs = []
    while True:
        param = reader.take()
        if param not in reader.params:
            reader.i -= 1
            raise reader.fail(f"a condition on one of {', '.join(params)}")
        reader.take(">")
        limit = reader.number()
        reader.take("->")
        pairs.append((reader.params.index(param), limit, tuple(reader.items(None, direct=False))))
        if reader.done():
            break
        reader.take("|")
    return Production(pname, reader.params, tuple(pairs))


# --------------------------------------------------------------------------------------------------
# Derivation.


def _clamp(v: float) -> float:
    if v != v:  # NaN
        return 0.0
    return LIMIT if v > LIMIT else -LIMIT if v < -LIMIT else v


def _value(expr: tuple, actual: tuple) -> float:
    kind = expr[0]
    if kind == "k":
        return expr[1]
    if kind == "p":
        return actual[expr[1]] if expr[1] < len(actual) else 0.0
    _, op, a, b = expr
    x, y = _value(a, actual), _value(b, actual)
    if op == "+":
        return _clamp(x + y)
    if op == "-":
        return _clamp(x - y)
    if op == "*":
        return _clamp(x * y)
    return _clamp(x / y) if y != 0 else 0.0


def _substitute(items: tuple | list, actual: tuple) -> tuple:
    """The successor ``items`` with the actual parameters put in (a piece of a word)."""
    out = []
    for item in items:
        kind = item[0]
        if kind == "c":
            out.append(("c", item[1], _value(item[2], actual)))
        elif kind == "call":
            out.append(("call", item[1], tuple(_value(e, actual) for e in item[2])))
        elif kind == "[":
            out.append(("[", _substitute(item[1], actual)))
        else:
            out.append(("{", _value(item[1], actual), _substitute(item[2], actual)))
    return tuple(out)


def _size(word: tuple) -> int:
    n = 0
    for item in word:
        n += 1
        if item[0] == "[":
            n += _size(item[1])
        elif item[0] == "{":
            n += _size(item[2])
    return n


def _step(word: tuple, system: System, budget: list[int]) -> tuple:
    """One derivation step: every call replaced in parallel by its successor (or by nothing)."""
    out = []
    for item in word:
        kind = item[0]
        if kind == "call":
            production = system.productions.get(item[1])
            if production is None:
                continue
            args = item[2]
            if len(args) != len(production.params):
                continue  # a module matches only a predecessor with as many parameters
            for index, limit, successor in production.pairs:
                if args[index] > limit:
                    piece = _substitute(successor, args)
                    budget[0] -= _size(piece)
                    if budget[0] < 0:
                        raise OverflowError
                    out.extend(piece)
                    break
        elif kind == "[":
            out.append(("[", _step(item[1], system, budget)))
        elif kind == "{":
            out.append(("{", item[1], _step(item[2], system, budget)))
        else:
            budget[0] -= 1
            out.append(item)
    return tuple(out)


def derive(system: System, max_modules: int = MAX_MODULES) -> tuple[tuple, int, bool]:
    """``(word, steps done, capped)``: the axiom rewritten ``system.iterations`` times, stopping at the
    last word of at most ``max_modules`` modules."""
    word = system.axiom
    for step in range(system.iterations):
        try:
            word = _step(word, system, [max_modules])
        except OverflowError:
            return word, step, True
    return word, system.iterations, False


def _fmt(v: float) -> str:
    return f"{v:g}"


def command_string(word: tuple, *, calls: bool = True) -> str:
    """The word in the paper's notation: ``[{ [forward(6)] left(1) }(4)] up(1) ...`` (calls as
    ``P1(6)``; ``calls=False`` drops them, as development does after the last step)."""
    parts: list[str] = []
    for item in word:
        kind = item[0]
        if kind == "c":
            parts.append(f"{COMMANDS[item[1]]}({_fmt(item[2])})")
        elif kind == "call":
            if calls:
                parts.append(f"{item[1]}({', '.join(map(_fmt, item[2]))})")
        elif kind == "[":
            parts.append(f"[{command_string(item[1], calls=calls)}]")
        else:
            parts.append(f"{{ {command_string(item[2], calls=calls)} }}({_fmt(item[1])})")
    return " ".join(p for p in parts if p)


# --------------------------------------------------------------------------------------------------
# The voxel turtle.

_AXES = {"^": (0, 1), "v": (0, 1), "<": (0, 2), ">": (0, 2), "/": (1, 2), "\\": (1, 2)}


def _rotated(frame: tuple, symbol: str, n: int) -> tuple:
    """The turtle's frame (X heading, Y, Z as integer world vectors) after ``symbol(n)``."""
    quarter = n % 4
    if symbol in ("v", ">", "\\"):
        quarter = (-quarter) % 4
    a, b = _AXES[symbol]  # rotating about the third axis turns a into b
    axes = [frame[0], frame[1], frame[2]]
    for _ in range(quarter):
        axes[a], axes[b] = axes[b], tuple(-c for c in axes[a])
    return tuple(axes)


def _orientations() -> tuple[list[tuple], dict[str, list[list[int]]]]:
    """The 24 frames the turtle can take, and for each rotation symbol and quarter-turn count
    (0..3) the frame each frame turns into (by index): a rotation is a table look-up."""
    frames = [((1, 0, 0), (0, 1, 0), (0, 0, 1))]
    index = {frames[0]: 0}
    todo = [frames[0]]
    while todo:
        frame = todo.pop()
        for symbol in _AXES:
            turned = _rotated(frame, symbol, 1)
            if turned not in index:
                index[turned] = len(frames)
                frames.append(turned)
                todo.append(turned)
    turns = {symbol: [[index[_rotated(f, symbol, q)] for f in frames] for q in range(4)]
             for symbol in _AXES}
    return frames, turns


_FRAMES, _TURNS = _orientations()
# A cell (x, y, z) is byte x * GRID * GRID + y * GRID + z of the flat grid; a frame's heading is one
# axis: its index stride, and which coordinate it moves along (to stop a move at the grid's edge).
_STRIDES = (GRID * GRID, GRID, 1)
_HEADINGS = [next((axis, c) for axis, c in enumerate(f[0]) if c) for f in _FRAMES]


@dataclass(frozen=True)
class Table:
    """A developed structure: ``voxels`` (GRID^3 bool, indexed ``[x, y, z]``, ``y`` up) and how it
    was built (derivation steps, commands run, modules in the final word, what capped it)."""

    voxels: np.ndarray
    steps: int
    commands: int
    modules: int
    capped: str | None

    @property
    def n_voxels(self) -> int:
        return int(self.voxels.sum())

    def digest(self) -> str:
        """A hash of the filled cells: equal digests, equal tables."""
        return hashlib.sha256(np.packbits(self.voxels).tobytes()).hexdigest()[:16]


class _Turtle:
    """The LOGO-style turtle over a flat byte grid (one byte a cell), its frame one of ``_FRAMES``."""

    def __init__(self, max_commands: int) -> None:
        self.cells = bytearray(GRID ** 3)
        x, y, z = START
        self.pos = [x, y, z]
        self.cells[x * GRID * GRID + y * GRID + z] = 1
        self.frame = 0
        self.left = max_commands
        self.run = 0
        self.memo: dict[tuple, tuple[tuple[int, int, int], int, int]] = {}

    @property
    def grid(self) -> np.ndarray:
        return np.frombuffer(bytes(self.cells), dtype=np.uint8).reshape(GRID, GRID, GRID).astype(bool)

    def move(self, n: float, sign: int) -> None:
        steps = int(n)  # truncation towards zero
        if steps < 0:
            steps, sign = -steps, -sign
        axis, c = _HEADINGS[self.frame]
        c *= sign
        pos = self.pos
        at = pos[axis]
        room = GRID - 1 - at if c > 0 else at      # cells left before the grid's edge
        if steps > room:
            steps = room
        if steps <= 0:
            return
        stride = _STRIDES[axis]
        here = pos[0] * GRID * GRID + pos[1] * GRID + pos[2]
        if c > 0:
            self.cells[here + stride:here + stride * (steps + 1):stride] = _ONES[steps]
        else:
            self.cells[here - stride * steps:here:stride] = _ONES[steps]
        pos[axis] = at + c * steps

    def run_items(self, items: tuple) -> None:
        for item in items:
            if self.left <= 0:
                return
            kind = item[0]
            if kind == "c":
                self.left -= 1
                self.run += 1
                symbol = item[1]
                if symbol == "f":
                    self.move(item[2], 1)
                elif symbol == "b":
                    self.move(item[2], -1)
                else:
                    self.frame = _TURNS[symbol][int(item[2]) % 4][self.frame]
            elif kind == "[":
                pos, frame = list(self.pos), self.frame
                self.run_block(item[1])
                self.pos, self.frame = pos, frame
            elif kind == "{" and _has_command(item[2]):  # repeating nothing would only cost time
                body = item[2]
                for _ in range(max(0, int(item[1]))):
                    if self.left <= 0:
                        return
                    self.run_block(body)

    def run_block(self, items: tuple) -> None:
        """Run a bracket's or a repeated block's ``items``. The turtle's path depends only on where it
        starts and how it faces (a move stops at the grid's edge, never at a filled cell), so a block
        run again from a state it ran from before fills no new cell: it only moves the turtle to the
        same end and counts the same commands, which a memo of (block, start) gives at once."""
        key = (id(items), self.pos[0], self.pos[1], self.pos[2], self.frame)
        seen = self.memo.get(key)
        if seen is not None:
            end, frame, count = seen
            if count >= self.left:     # the cap falls inside: later commands are skipped anyway
                self.run += self.left
                self.left = 0
                return
            self.left -= count
            self.run += count
            self.pos, self.frame = list(end), frame
            return
        before = self.run
        self.run_items(items)
        if self.left > 0:              # run whole: remember where it ends
            self.memo[key] = (tuple(self.pos), self.frame, self.run - before)


_ONES = [b"\x01" * k for k in range(GRID + 1)]


_STILL = tuple(range(len(_FRAMES)))   # the turn that leaves every frame as it is


def same_cells_form(word: tuple) -> tuple | None:
    """A form of ``word`` equal for words whose turtle fills the same cells (``None`` when the
    command cap cuts it: then only the word itself says). Moves become signed whole steps, runs of
    moves one way merge (a move stops at the grid's edge, so ``f(3) f(2)`` fills what ``f(5)`` does),
    runs of turns one turn (a map over the 24 frames), and what cannot fill a cell goes: moves of 0,
    blocks repeated under once or holding no command, brackets that only turn, the turns before a
    bracket closes or the word ends. A block run once is its body; one that only turns, one turn."""
    if _commands(word) > MAX_COMMANDS:
        return None
    return _unturned(_form(word))


def _unturned(form: tuple) -> tuple:
    """``form`` without the turn it ends with: no move follows it (the word ends, or a bracket
    closes and the turtle turns back)."""
    return form[:-1] if form and form[-1][0] == "r" else form


def _form(items: tuple) -> tuple:
    out: list = []
    for item in items:
        kind = item[0]
        if kind == "c":
            symbol = item[1]
            if symbol in ("f", "b"):
                _put_move(out, int(item[2]) if symbol == "f" else -int(item[2]))
            else:
                _put_turn(out, tuple(_TURNS[symbol][int(item[2]) % 4]))
        elif kind == "[":
            inner = _unturned(_form(item[1]))
            if inner:
                out.append(("[", inner))
        elif kind == "{":
            times, body = max(0, int(item[1])), _form(item[2])
            if times == 0 or not body:
                continue
            if times == 1:
                for piece in body:
                    _put(out, piece)
            elif len(body) == 1 and body[0][0] == "r":
                for _ in range(1 + (times - 1) % len(_FRAMES)):   # a turn repeated 24 times is no turn
                    _put_turn(out, body[0][1])
            else:
                out.append(("{", times, body))
    return tuple(out)


def _put(out: list, piece: tuple) -> None:
    if piece[0] == "m":
        _put_move(out, piece[1])
    elif piece[0] == "r":
        _put_turn(out, piece[1])
    else:
        out.append(piece)


def _put_move(out: list, steps: int) -> None:
    if steps == 0:
        return
    if out and out[-1][0] == "m" and (out[-1][1] > 0) == (steps > 0):
        steps += out.pop()[1]
    out.append(("m", steps))


def _put_turn(out: list, turn: tuple) -> None:
    if out and out[-1][0] == "r":
        first = out.pop()[1]
        turn = tuple(turn[f] for f in first)
    if turn != _STILL:
        out.append(("r", turn))


def _commands(items: tuple) -> int:
    """The commands the turtle would run over ``items``, blocks replicated, with no cap."""
    n = 0
    for item in items:
        if item[0] == "c":
            n += 1
        elif item[0] == "[":
            n += _commands(item[1])
        elif item[0] == "{":
            n += max(0, int(item[1])) * _commands(item[2])
    return n


def _has_command(items: tuple) -> bool:
    """Whether running ``items`` runs at least one command (``{ }(0)`` and calls run none)."""
    for item in items:
        kind = item[0]
        if kind == "c" or (kind == "[" and _has_command(item[1])) or \
                (kind == "{" and int(item[1]) > 0 and _has_command(item[2])):
            return True
    return False


def build(word: tuple, max_commands: int = MAX_COMMANDS) -> tuple[np.ndarray, int, bool]:
    """Run the turtle over ``word`` (calls are skipped): ``(voxels, commands run, capped)``."""
    turtle = _Turtle(max_commands)
    turtle.run_items(word)
    return turtle.grid, turtle.run, turtle.left <= 0 and _commands(word) > turtle.run


def develop(text: str, *, max_modules: int = MAX_MODULES, max_commands: int = MAX_COMMANDS) -> Table:
    """Parse ``text``, rewrite it, and build its voxels (a pure function of its arguments)."""
    system = parse(text)
    word, steps, capped_modules = derive(system, max_modules)
    voxels, commands, capped_commands = build(word, max_commands)
    capped = "modules" if capped_modules else "commands" if capped_commands else None
    return Table(voxels, steps, commands, _size(word), capped)


# --------------------------------------------------------------------------------------------------
# Criteria and fitness (section 3).


def hull_area(cells: np.ndarray) -> float:
    """The area of the convex hull of unit squares at integer ``cells`` (N, 2); 0 when empty."""
    if not len(cells):
        return 0.0
    cells = np.asarray(cells, dtype=np.int64)
    points = []
    for row in np.unique(cells[:, 1]):
        xs = cells[cells[:, 1] == row, 0]
        lo, hi = int(xs.min()), int(xs.max()) + 1
        points += [(lo, int(row)), (hi, int(row)), (lo, int(row) + 1), (hi, int(row) + 1)]
    pts = sorted(set(points))

    def cross(o, a, b) -> int:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    hull = lower[:-1] + upper[:-1]
    twice = sum(hull[i][0] * hull[i - 1][1] - hull[i - 1][0] * hull[i][1] for i in range(len(hull)))
    return abs(twice) / 2.0


@lru_cache(maxsize=4096)
def _layer_area(packed: bytes) -> float:
    """The hull area of one layer, its cells packed as bits (cached: a table's legs repeat one
    layer many times, and a child shares most layers with its parent)."""
    layer = np.unpackbits(np.frombuffer(packed, dtype=np.uint8), count=GRID * GRID).reshape(GRID, GRID)
    xs, zs = np.nonzero(layer)
    return hull_area(np.column_stack([xs, zs]))


def criteria(voxels: np.ndarray) -> dict[str, float]:
    """``height``, ``surface``, ``stability``, ``excess`` and the ``voxels`` count of a structure."""
    layers = voxels.sum(axis=(0, 2))
    filled = np.flatnonzero(layers)
    total = int(layers.sum())
    if not total:
        return dict.fromkeys(CRITERIA, 0.0)
    top = int(filled[-1])
    surface = int(layers[top])
    stability = 0.0
    for y in filled[filled < top]:
        stability += _layer_area(np.packbits(voxels[:, y, :]).tobytes())
    return {"height": float(top), "surface": float(surface), "stability": stability,
            "excess": float(total - surface), "voxels": float(total)}


def top_filled_share(voxels: np.ndarray) -> float:
    """The top layer's voxels over the area of their convex hull: 1 for a solid top, far less for a
    lattice of one-voxel bars spread over the same hull (0 for an empty structure)."""
    layers = np.flatnonzero(voxels.sum(axis=(0, 2)))
    if not len(layers):
        return 0.0
    xs, zs = np.nonzero(voxels[:, int(layers[-1]), :])
    return float(len(xs)) / hull_area(np.column_stack([xs, zs]))


def fitness(values: dict[str, float]) -> float:
    """``height * surface * stability / excess``, 0 when nothing lies below the top layer (maximised)."""
    excess = values["excess"]
    if excess <= 0:
        return 0.0
    return values["height"] * values["surface"] * values["stability"] / excess


# --------------------------------------------------------------------------------------------------
# Export: the voxels' outer faces as one triangle mesh (what a 3D printer takes), and a picture.

_FACES = {  # direction -> the four corners (offsets) of the cell face on that side, counter-clockwise
    (1, 0, 0): ((1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)),
    (-1, 0, 0): ((0, 0, 0), (0, 0, 1), (0, 1, 1), (0, 1, 0)),
    (0, 1, 0): ((0, 1, 0), (0, 1, 1), (1, 1, 1), (1, 1, 0)),
    (0, -1, 0): ((0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)),
    (0, 0, 1): ((0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)),
    (0, 0, -1): ((0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 0, 0)),
}


def mesh_arrays(voxels: np.ndarray, cell: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, faces)`` of the structure's outer faces, z up (grid ``(x, y, z)`` -> ``(x, -z, y)``,
    a rotation), faces pointing outwards; shared corners are one vertex, in a fixed order."""
    padded = np.pad(voxels, 1)
    quads = []
    for (dx, dy, dz), corners in _FACES.items():
        neighbour = padded[1 + dx:padded.shape[0] - 1 + dx, 1 + dy:padded.shape[1] - 1 + dy,
                           1 + dz:padded.shape[2] - 1 + dz]
        cells = np.argwhere(voxels & ~neighbour)
        if len(cells):
            quads.append(cells[:, None, :] + np.asarray(corners)[None, :, :])
    if not quads:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    corners = np.concatenate(quads)                    # (Q, 4, 3) grid corners
    unique, inverse = np.unique(corners.reshape(-1, 3), axis=0, return_inverse=True)
    idx = inverse.reshape(-1, 4)
    faces = np.concatenate([idx[:, [0, 1, 2]], idx[:, [0, 2, 3]]])
    x, y, z = unique[:, 0], unique[:, 1], unique[:, 2]
    vertices = np.column_stack([x, -z, y]).astype(np.float64) * cell
    return vertices, faces.astype(np.int64)


TOP_COLOUR = np.asarray([0.16, 0.50, 0.62])     # the table top (layer Y_max)
BODY_COLOUR = np.asarray([0.78, 0.55, 0.32])    # legs and everything below the top
GROUND_COLOUR = np.asarray([0.42, 0.30, 0.22])  # what touches the ground (layer 0)


def draw(ax: Any, voxels: np.ndarray, *, elev: float = 35.264, azim: float = -45.0) -> None:
    """Draw the structure on a matplotlib 3D axes in an isometric (orthographic) view: its outer
    faces, the top layer in blue, the voxels touching the ground dark and the rest wood, every voxel
    face outlined, on a ground grid."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    vertices, faces = mesh_arrays(voxels)
    ax.set_axis_off()
    ax.set_proj_type("ortho")
    ax.view_init(elev=elev, azim=azim)
    if not len(faces):
        return
    tris = vertices[faces]
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    light = np.asarray([0.35, -0.55, 0.75])
    shade = 0.55 + 0.45 * np.clip(normals @ light / (np.linalg.norm(normals, axis=1) + 1e-12), 0, 1)
    top = float(vertices[:, 2].max())
    low = tris[:, :, 2].min(axis=1)   # the face's lowest corner: which layer's voxel it bounds
    colours = np.where((low >= top - 1)[:, None], TOP_COLOUR,
                       np.where((low < 1)[:, None], GROUND_COLOUR, BODY_COLOUR))
    ax.add_collection3d(Poly3DCollection(tris, facecolors=np.clip(colours * shade[:, None], 0, 1),
                                         edgecolors="none"))
    half_count = len(tris) // 2   # mesh_arrays: each face's triangles (0, 1, 2), then (0, 2, 3)
    first, second = tris[:half_count], tris[half_count:]
    outline = np.concatenate([first[:, [0, 1]], first[:, [1, 2]], second[:, [1, 2]], second[:, [2, 0]]])
    ax.add_collection3d(Line3DCollection(outline, colors=(0.1, 0.1, 0.1, 0.3), linewidths=0.2))
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    ground = [[(x, lo[1], 0), (x, hi[1], 0)] for x in np.linspace(lo[0], hi[0], 5)] + \
             [[(lo[0], y, 0), (hi[0], y, 0)] for y in np.linspace(lo[1], hi[1], 5)]
    ax.add_collection3d(Line3DCollection(ground, colors=(0.5, 0.5, 0.5, 0.35), linewidths=0.5))
    centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1.0)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))


def draw_plan(ax: Any, voxels: np.ndarray) -> None:
    """The table seen from above on a 2D axes: the top layer's voxels (blue) over the ground
    footprint (layer 0, dark) and the rest of the structure's shadow (light), one cell a voxel."""
    image = np.ones((GRID, GRID, 3))
    layers = np.flatnonzero(voxels.sum(axis=(0, 2)))
    if len(layers):
        image[voxels.any(axis=1)] = 0.86
        image[voxels[:, 0, :]] = GROUND_COLOUR
        image[voxels[:, int(layers[-1]), :]] = TOP_COLOUR
    ax.imshow(image.transpose(1, 0, 2), origin="lower", interpolation="nearest")
    ax.set_xticks([0, GRID - 1])
    ax.set_yticks([0, GRID - 1])
    ax.tick_params(labelsize=6, length=2)
    ax.set_title("from above: top (blue), ground contact (dark)", fontsize=7)


def draw_side(ax: Any, voxels: np.ndarray) -> None:
    """The table seen from the front on a 2D axes (x across, height up): each column's filled
    cells, the top layer blue, the ground layer dark, the rest wood, so the legs' height shows."""
    image = np.ones((GRID, GRID, 3))
    seen = voxels.any(axis=2)                     # (x, y)
    layers = np.flatnonzero(voxels.sum(axis=(0, 2)))
    if len(layers):
        image[seen] = BODY_COLOUR
        image[:, 0][seen[:, 0]] = GROUND_COLOUR
        top = int(layers[-1])
        image[:, top][seen[:, top]] = TOP_COLOUR
    ax.imshow(image.transpose(1, 0, 2), origin="lower", interpolation="nearest")
    ax.set_xticks([0, GRID - 1])
    ax.set_yticks([0, GRID - 1])
    ax.tick_params(labelsize=6, length=2)
    ax.set_title("from the front: legs and top", fontsize=7)


def voxel_count_text(table: Table, values: dict[str, float]) -> str:
    """A one-line caption: voxels, height, surface, stability, excess and the paper's fitness."""
    return (f"{table.n_voxels} voxels, height {values['height']:g}, surface {values['surface']:g}, "
            f"stability {values['stability']:g}, excess {values['excess']:g}, "
            f"fitness {fitness(values):.4g}" + (f" (capped: {table.capped})" if table.capped else ""))


def is_connected(voxels: np.ndarray) -> bool:
    """Whether the filled cells form one face-connected structure (a flood fill)."""
    cells = np.argwhere(voxels)
    if not len(cells):
        return True
    seen = np.zeros_like(voxels)
    stack = [tuple(cells[0])]
    seen[stack[0]] = True
    count = 0
    while stack:
        x, y, z = stack.pop()
        count += 1
        for dx, dy, dz in _FACES:
            n = (x + dx, y + dy, z + dz)
            if all(0 <= c < GRID for c in n) and voxels[n] and not seen[n]:
                seen[n] = True
                stack.append(n)
    return count == len(cells)


__all__ = ["COMMANDS", "CRITERIA", "GRID", "MAX_COMMANDS", "MAX_MODULES", "Production", "System",
           "Table", "TablesError", "build", "command_string", "criteria", "derive", "develop", "draw",
           "draw_plan", "draw_side", "fitness", "hull_area", "is_connected", "mesh_arrays", "parse",
           "top_filled_share"]
