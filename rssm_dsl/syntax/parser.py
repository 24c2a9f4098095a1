"""Parse RSSM text into an AST, reporting several syntax errors per run.

Lark's LALR parser is driven token by token so that an error does not end the parse:
a missing closer (`}`, `)`, `]`, `:`) is inserted when that lets the parser go on,
otherwise the offending token is dropped. Errors closer than three accepted tokens to the
previous one are not reported (they are almost always echoes of it).

Hostile input costs time linear in its size, and little of it:

- the parse stops after MAX_ERRORS reported syntax errors, or MAX_RECOVERIES errors
  recovered from (reported or echoes), with a last error saying where it stopped;
- a run of characters that start no token is one error (E006), an unclosed string skips
  the rest of its line, an unclosed block comment ends the file (E007): the lexer never
  rescans the rest of a line or file once per character;
- nesting is measured token by token as the parser accepts them (:class:`_Nesting`), so
  that E008 is reported at the 65th level of brackets, operators or `if`, not after the
  parser has read a megabyte of `1+1+...` to the end of the chain.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from functools import cache, partial
from typing import Any

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedToken
from lark.lexer import BasicLexer, PatternStr, UnlessCallback
from lark.parse_tree_builder import ChildFilterLALR_NoPlaceholders, ExpandSingleChild
from lark.parsers.lalr_analysis import Shift
from lark.parsers.lalr_parser_state import ParserState

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.resources import grammar_text
from rssm_dsl.source import NOT_LINE_BREAKS, SourceFile, Span, describe_char
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.build import (
    BINARY_PRECEDENCE,
    MAX_DEPTH,
    PREFIX_PRECEDENCE,
    AstBuilder,
    Callbacks,
    NestingTooDeep,
    building,
)

MAX_ERRORS = 50          # syntax errors reported in one file; at the next one the parse stops
MAX_RECOVERIES = 1000    # errors recovered from in one file, reported or not (echoes)
_CLOSERS = ("}", ")", "]", ":")
_WHITESPACE = frozenset(" \t\f\r\n")


@dataclass(frozen=True)
class ParseResult:
    module: ast.Module | None
    diagnostics: tuple[Diagnostic, ...]


@cache
def _lark() -> Lark:
    return Lark(
        grammar_text(),
        parser="lalr",
        lexer="basic",
        maybe_placeholders=True,
        transformer=Callbacks(),
        cache=True,          # the grammar analysis, in a temp file keyed by its hash
    )


# An action of the LALR table as _Driver._read reads it: (-1, state to go to, None) for a
# shift; (n, callback, goto) for a reduction of a rule of n symbols, whose callback makes its
# value from the n values on top of the stack, goto the state to push by the state left on
# top of the stack. Two callbacks are not called: None, a rule whose value is its only
# symbol's (`?rule: other`), and _APPEND, a rule `x*` that goes on (its callback appends
# the other values to the list of the tree of `x*` below them, and wraps that list in a new
# tree of the same name: the driver appends them, and keeps the tree).
_Action = tuple[int, Any, Any]
_APPEND = object()
# what the lexer does with a terminal besides making a token of it: nothing (an ignored
# terminal), count its line breaks, look it up among the keywords (NAME), check whether
# it starts an unclosed /* (BINOP)
_IGNORED, _NEWLINES, _KEYWORDS, _SLASH = 1, 2, 4, 8
_SLASH_TERMINAL = "BINOP"


@dataclass(frozen=True)
class _Tables:
    """Lark's lexer and LALR table of the grammar, in the form the driver's loop reads fastest
    (the same regular expressions, keyword callbacks, ignored terminals, actions and rule
    callbacks as Lark's own BasicLexer and ParserState.feed_token use)."""

    match: Callable[[str, int], re.Match[str] | None]
    keywords: dict[str, dict[str, str]]      # NAME -> {"if": "IF", ...} (UnlessCallback)
    # terminal -> what the lexer does besides making a token of it (_IGNORED | _NEWLINES |
    # _KEYWORDS | _SLASH); the others are not in it
    special: dict[str, int]
    actions: dict[int, dict[str, _Action]]   # state -> terminal -> action
    states: dict[int, dict[str, Any]]        # Lark's table (for the expected terminals)
    # (state below, state on top, terminal) -> the state on top after the reductions of
    # `?rule: other` that terminal makes from there (filled as they are met)
    units: dict[tuple[int, int, str], int]

    def expected(self, state: int) -> set[str]:
        """The terminals the parser accepts in `state` (as Lark's UnexpectedToken has them)."""
        return {s for s in self.states[state] if s.isupper()}

    def unit(self, below: int, top: int, kind: str) -> int:
        """The state on top after `kind` has made every reduction of a `?rule: other` it
        makes from (below, top); each replaces the state on top with its goto from below."""
        key = (below, top, kind)
        while True:
            action = self.actions[top].get(kind)
            if action is None or action[0] < 0 or action[1] is not None:
                self.units[key] = top
                return top
            top = action[2][below]


def _scanner(lexer: BasicLexer) -> tuple[Callable[[str, int], re.Match[str] | None],
                                         dict[str, dict[str, str]]]:
    """The lexer's match function and keyword tables, as BasicLexer.next_token uses them."""
    scanner = lexer.scanner
    keywords: dict[str, dict[str, str]] = {}
    for name, callback in lexer.callback.items():
        # the only callbacks of a grammar without lexer callbacks: a keyword lexed as a name
        if not isinstance(callback, UnlessCallback):
            raise TypeError(f"unexpected lexer callback for {name}: {callback!r}")
        words = callback.scanner.terminals
        if not all(isinstance(t.pattern, PatternStr) and not t.pattern.flags for t in words):
            raise TypeError(f"unexpected keywords for {name}")
        keywords[name] = {t.pattern.value: t.name for t in words}
    patterns = list(scanner._mres)
    if len(patterns) == 1:
        return patterns[0].match, keywords

    def match(text: str, pos: int) -> re.Match[str] | None:
        for mre in patterns:
            m = mre.match(text, pos)
            if m:
                return m  # type: ignore[no-any-return]
        return None

    return match, keywords


@cache
def _tables() -> _Tables:
    lark = _lark()
    lexer = lark.parser.lexer
    assert isinstance(lexer, BasicLexer)
    match, keywords = _scanner(lexer)
    if lexer.ignore_types & set(keywords):
        raise TypeError("an ignored terminal has a lexer callback")
    parser = lark.parser.parser.parser
    states: dict[int, dict[str, Any]] = parser.parse_table.states
    callbacks = parser.callbacks
    if any(isinstance(k, str) for k in callbacks):
        raise TypeError("terminal callbacks of the parser are not supported")
    gotos: dict[str, dict[int, int]] = {}
    for state, row in states.items():
        for symbol, (kind, arg) in row.items():
            if kind is Shift:
                gotos.setdefault(symbol, {})[state] = arg
    reductions: dict[Any, _Action] = {}
    for rule, callback in callbacks.items():
        size = len(rule.expansion)
        if size == 1 and type(callback) is ExpandSingleChild:
            callback = None
        elif _appends(rule, callback):
            callback = _APPEND
        reductions[rule] = (size, callback, gotos.get(rule.origin.name, {}))
    actions = {state: {symbol: (-1, arg, None) if kind is Shift else reductions[arg]
                       for symbol, (kind, arg) in row.items()}
               for state, row in states.items()}
    special: dict[str, int] = {}
    for flag, names in ((_IGNORED, lexer.ignore_types), (_NEWLINES, lexer.newline_types),
                        (_KEYWORDS, keywords), (_SLASH, [_SLASH_TERMINAL])):
        for name in names:
            special[name] = special.get(name, 0) | flag
    return _Tables(match, keywords, special, actions, states, {})


def _appends(rule: Any, callback: Any) -> bool:
    """Whether `callback` is Lark's for a rule `x* : x* a b ...` (ChildFilterLALR's
    left-recursion case, then a tree named after the rule)."""
    if type(callback) is not ChildFilterLALR_NoPlaceholders:
        return False
    size = len(rule.expansion)
    builder = callback.node_builder
    return (callback.to_include == [(i, i == 0) for i in range(size)] and size > 1
            and rule.expansion[0] == rule.origin
            and isinstance(builder, partial) and builder.func is Tree
            and builder.args == (rule.origin.name,) and not builder.keywords)


@cache
def _token_start() -> re.Pattern[str]:
    """Matches where some terminal of the grammar matches (to skip what starts none)."""
    return re.compile("|".join(f"(?:{t.pattern.to_regexp()})" for t in _lark().terminals))


@cache
def _terminal_text() -> dict[str, str]:
    """Terminal name -> how to show it to a person."""
    names: dict[str, str] = {
        "NAME": "a name", "INT": "an integer", "FLOAT": "a number", "STRING": "a string",
        "$END": "end of file",
    }
    for term in _lark().terminals:
        pattern = term.pattern
        if term.name not in names and pattern.type == "str":
            names[term.name] = f"'{pattern.value}'"
    return names


@cache
def _closer_terminals() -> dict[str, str]:
    """'}' -> its terminal name."""
    out: dict[str, str] = {}
    for term in _lark().terminals:
        if term.pattern.type == "str" and term.pattern.value in _CLOSERS:
            out[term.pattern.value] = term.name
    return out


_UNIT = "Hz"          # the unit a rate without one is given, to go on parsing
# what a reserved word that is often meant as a name does in RSSM
_KEYWORD_ROLES = {
    "error": " (it starts a condition: `error NAME when ...`)",
    "terminal": " (it starts a condition: `terminal NAME when ...`)",
}


@cache
def _unit_terminals() -> dict[str, str]:
    """'Hz' -> its terminal name, 'kHz' -> its."""
    return {str(t.pattern.value): t.name for t in _lark().terminals
            if t.pattern.type == "str" and t.pattern.value in ("Hz", "kHz")}


@cache
def _keyword_terminals() -> frozenset[str]:
    """The terminals of the reserved words (lexed as names, then looked up)."""
    return frozenset(t for words in _tables().keywords.values() for t in words.values())


def _describe(tok: Token) -> str:
    if tok.type == "$END":
        return "end of file"
    if tok.type == "NAME":
        return f"name '{_shortened(tok.value)}'"
    if tok.type in ("INT", "FLOAT"):
        return f"number {_shortened(tok.value)}"
    if tok.type == "STRING":
        return f"string {_shortened(tok.value)}"
    return f"'{tok.value}'"


def _shortened(text: str, width: int = 40) -> str:
    return text if len(text) <= width else text[: width - 1] + "…"


_EXPRESSION_START = {"INT", "FLOAT", "NAME", "LPAR", "LSQB", "LBRACE", "MINUS", "TRUE", "FALSE",
                     "IF", "NOT"}


def _expected(names: set[str]) -> str:
    extra: set[str] = set()
    if {"INT", "FLOAT"} <= names:
        names = names - _EXPRESSION_START
        extra.add("an expression")
    shown = sorted({_terminal_text().get(n, n) for n in names} | extra)
    if not shown:
        return "nothing more"
    if len(shown) > 8:
        shown = [*shown[:8], "…"]
    return "one of " + ", ".join(shown) if len(shown) > 1 else shown[0]


# Characters pasted from papers and word processors that look like RSSM operators.
_LOOKALIKES = {
    "\u2212": "-", "\u2013": "-", "\u2014": "-", "\u00d7": "*", "\u22c5": "*",
    "\u00f7": "/", "\u2264": "<=", "\u2265": ">=", "\u2260": "!=", "\u201c": '"',
    "\u201d": '"', "\u2254": ":=",
}


def _character_hint(char: str) -> str:
    if char in _LOOKALIKES:
        return f"this only looks like '{_LOOKALIKES[char]}': type '{_LOOKALIKES[char]}' instead"
    if char == "#":
        return "comments start with //"
    if char in NOT_LINE_BREAKS:
        return "it is not a line break in RSSM: end the line with an ordinary line break"
    if char.isspace():
        return "replace it with an ordinary space"
    return "remove it; names are ASCII letters, digits and '_'"


def _trial(state: ParserState[Any]) -> ParserState[Any]:
    """A copy of the parser state to try tokens on. Lark's LALR tree builder appends to the
    children of the trees of `x*` on the stack in place (ChildFilterLALR): they are copied
    too, so that what a trial reduces never shows in what the parse builds (a trial used to
    add its placeholder tokens, without a position, to the real parse's lists)."""
    trial = state.copy(deepcopy_values=False)
    trial.value_stack = [Tree(v.data, list(v.children)) if isinstance(v, Tree) else v
                         for v in trial.value_stack]
    return trial


class _Stop(Exception):
    """The parse ends here: too many errors."""

    def __init__(self, span: Span) -> None:
        super().__init__("too many syntax errors")
        self.span = span


# ------------------------------------------------------------------------------ nesting

# what a token is to _Nesting
_OPEN, _CLOSE, _OPERAND, _BINARY, _MINUS, _NOT, _IF, _THEN, _ELSE, _POSTFIX = range(10)
_ROLE = {
    "LPAR": _OPEN, "LSQB": _OPEN, "LBRACE": _OPEN, "RPAR": _CLOSE, "RSQB": _CLOSE,
    "RBRACE": _CLOSE, "INT": _OPERAND, "FLOAT": _OPERAND, "NAME": _OPERAND, "TRUE": _OPERAND,
    "FALSE": _OPERAND, "BINOP": _BINARY, "AND": _BINARY, "OR": _BINARY, "MINUS": _MINUS,
    "NOT": _NOT, "IF": _IF, "THEN": _THEN, "ELSE": _ELSE, "DOT": _POSTFIX, "IN": _POSTFIX,
}
# the states of an `if` whose expression is still open
_IF_CONDITION, _IF_THEN, _IF_ELSE = range(3)


class _Level:
    """The expression being read at one level of brackets."""

    __slots__ = ("after_operand", "ifs", "ops", "reach", "start")

    def __init__(self) -> None:
        self.after_operand = False
        # the operators of the chain not yet combined, as precedence climbing (build.py)
        # holds them: (is_prefix, precedence, depth of the left operand)
        self.ops: list[tuple[bool, int, int]] = []
        # reach[i]: the largest `depth of the left operand + i + 1` of the binary operators
        # of ops[:i + 1] (0 if none); the depth of the chain is max(len(ops), reach[-1])
        self.reach: list[int] = []
        self.ifs: list[int] = []          # the `if`s around the chain, innermost last
        self.start = -1                   # offset of the expression's first token

    def reset(self) -> None:
        self.after_operand = False
        self.ops.clear()
        self.reach.clear()
        self.ifs.clear()
        self.start = -1


class _Nesting:
    """How deep the AST of the tokens accepted so far must be, kept up to date token by
    token, so that E008 is reported as soon as it is certain.

    Brackets are counted (more than MAX_DEPTH open is E008 whether or not they add a level
    to the AST). Inside the brackets, the operators of a chain are combined as precedence
    climbing does (build.py, with the same precedences) with every operand counted as a
    leaf, and the `if`s whose expression is still open are counted around it: that depth is
    a lower bound of the depth the AST builder measures when the expression is reduced, and
    it only grows as the chain goes on. So a too-deep expression is reported at its 65th
    level instead of after the parser has read it to its end (a megabyte of `1+1+...`),
    and nothing the builder would accept is refused.

    The depth is kept up to date as operators come (_Level.reach), and _check, which
    measures it from the operators and reports it, is only called once it passes the limit.
    """

    __slots__ = ("levels", "source")

    def __init__(self, source: SourceFile) -> None:
        self.source = source
        self.levels: list[_Level] = [_Level()]

    def reset(self) -> None:
        """After a syntax error: forget the expressions being read (brackets stay)."""
        for level in self.levels:
            level.reset()

    def accept(self, tok: Token) -> None:
        role = _ROLE.get(tok.type)
        level = self.levels[-1]
        if role is None:                  # a keyword or punctuation: the expression ends
            if level.start >= 0:
                level.reset()
        elif role == _OPERAND:
            if level.after_operand:       # `x := a  y := b`: a new statement
                level.reset()
            if level.start < 0:
                level.start = tok.start_pos or 0
            level.after_operand = True
        elif role == _BINARY or (role == _MINUS and level.after_operand):
            self._binary(level, tok)
        elif role in (_MINUS, _NOT):
            self._prefix(level, tok)
        elif role == _POSTFIX:
            level.after_operand = False   # `a.b`, `a in b`: the name follows
        elif role in (_OPEN, _CLOSE):
            self._bracket(level, role, tok)
        else:
            self._if(level, role, tok)

    def _binary(self, level: _Level, tok: Token) -> None:
        """A binary operator: combine the operators before it that bind at least as tightly
        (as build.py's _climb does)."""
        prec = BINARY_PRECEDENCE[tok.value]
        ops, reach = level.ops, level.reach
        cur = 0
        while ops:
            is_prefix, p, left = ops[-1]
            if p < prec or (p == prec and is_prefix):
                break
            ops.pop()
            reach.pop()
            cur = 1 + (cur if is_prefix else max(left, cur))
        top = cur + len(ops) + 1
        if reach and reach[-1] > top:
            top = reach[-1]
        ops.append((False, prec, cur))
        reach.append(top)
        level.after_operand = False
        if max(top, len(ops)) + len(level.ifs) > MAX_DEPTH:
            self._check(level, tok)

    def _prefix(self, level: _Level, tok: Token) -> None:
        if level.after_operand:
            level.reset()
        if level.start < 0:
            level.start = tok.start_pos or 0
        level.ops.append((True, PREFIX_PRECEDENCE[tok.value], 0))
        level.reach.append(level.reach[-1] if level.reach else 0)
        if max(level.reach[-1], len(level.ops)) + len(level.ifs) > MAX_DEPTH:
            self._check(level, tok)

    def _bracket(self, level: _Level, role: int, tok: Token) -> None:
        if role == _CLOSE:
            if len(self.levels) > 1:
                self.levels.pop()
            self.levels[-1].after_operand = True
            return
        if tok.type == "LBRACE" and level.after_operand:
            level.reset()                 # `... {` of a block
        if level.start < 0:
            level.start = tok.start_pos or 0
        self.levels.append(_Level())
        if len(self.levels) > MAX_DEPTH + 1:
            raise NestingTooDeep(self._span(tok), MAX_DEPTH,
                             f"brackets nested deeper than {MAX_DEPTH} levels (the braces of "
                             "the declarations around included)")

    def _if(self, level: _Level, role: int, tok: Token) -> None:
        ifs = level.ifs
        level.ops.clear()
        level.reach.clear()
        level.after_operand = False
        if role == _IF:
            if level.start < 0:
                level.start = tok.start_pos or 0
            ifs.append(_IF_CONDITION)
            if len(ifs) > MAX_DEPTH:
                self._check(level, tok)
            return
        # `then` and `else` end the `if`s of the part they close (`if if a then b else c
        # then ...`), then move their own `if` on
        wanted = _IF_CONDITION if role == _THEN else _IF_THEN
        while ifs and ifs[-1] == _IF_ELSE:
            ifs.pop()
        if not ifs or ifs[-1] != wanted:
            level.reset()
            return
        ifs[-1] = _IF_THEN if role == _THEN else _IF_ELSE

    def _check(self, level: _Level, tok: Token) -> None:
        depth = 0
        for is_prefix, _, left in reversed(level.ops):
            depth = 1 + (depth if is_prefix else max(left, depth))
        depth += len(level.ifs)
        if depth > MAX_DEPTH:
            end = tok.end_pos if tok.end_pos is not None else level.start
            raise NestingTooDeep(
                self.source.span(level.start, end), MAX_DEPTH,
                f"expression nested deeper than {MAX_DEPTH} levels (each operator of a chain "
                "such as a + b + c, and each `if`, is one level)")

    def _span(self, tok: Token) -> Span:
        start = tok.start_pos or 0
        return self.source.span(start, tok.end_pos if tok.end_pos is not None else start)


# ------------------------------------------------------------------------------ the driver

class _Driver:
    def __init__(self, source: SourceFile) -> None:
        self.source = source
        self.diagnostics: list[Diagnostic] = []
        self.accepted_since_error = 1_000_000
        self.recoveries = 0
        self.nesting = _Nesting(source)

    # -- reporting
    def _report(self, code: str, message: str, span: Span, hint: str | None = None,
                always: bool = False) -> None:
        """Report a syntax error, unless it is an echo of the previous one (``always``:
        report it anyway); stop the parse when there are too many."""
        self.recoveries += 1
        if self.accepted_since_error >= 3 or always:
            if len(self.diagnostics) >= MAX_ERRORS:
                raise _Stop(span)
            self.diagnostics.append(Diagnostic(code, message, span, hint))
        self.accepted_since_error = 0
        self.nesting.reset()
        if self.recoveries >= MAX_RECOVERIES:
            raise _Stop(span)

    def _token_span(self, tok: Token) -> Span:
        start = tok.start_pos if tok.start_pos is not None else len(self.source.text)
        end = tok.end_pos if tok.end_pos is not None else start
        if tok.type == "$END":
            start = end = len(self.source.text)
        return self.source.span(start, max(end, start))

    # -- the loop
    def run(self) -> Any:
        """The module's tree (None when nothing usable was recovered)."""
        state = _lark().parse_interactive(self.source.text).parser_state
        try:
            pos: int | None = 0
            while pos is not None:
                pos = self._read(state, pos)
                if pos is not None:
                    pos = self._skip(pos)
            return self._finish(state)
        except _Stop as stop:
            self.diagnostics.append(Diagnostic(
                "E005", "too many syntax errors: the parse stops here", stop.span,
                "fix the errors above and check again (the rest of the file is not read "
                f"after {MAX_ERRORS} errors)"))
            return None

    def _read(self, state: ParserState[Any], pos: int) -> int | None:
        """Lex the text from `pos` and feed its tokens to the parser, until the end of the
        text (None) or a character that starts no token (its offset, for _skip). An unclosed
        block comment is reported and ends the text.

        The lexer and the parser are Lark's, run in one loop (_Tables): the same terminals,
        priorities, keywords and ignored terminals as Lark's BasicLexer, the same tokens
        (positions, lines and columns included), and the same shifts, reductions and
        callbacks as ParserState.feed_token, but without one call per token to each (they
        were most of the time of a parse)."""
        tables = _tables()
        match, actions, units, unit = tables.match, tables.actions, tables.units, tables.unit
        special, keywords = tables.special, tables.keywords
        text = self.source.text
        n = len(text)
        state_stack, value_stack = state.state_stack, state.value_stack
        accept = self.nesting.accept
        new_str = str.__new__
        line, column = self.source.position(pos)
        line_start = pos - column + 1
        accepted = self.accepted_since_error     # (kept here, and in self around calls)
        while pos < n:
            m = match(text, pos)
            if m is None:
                self.accepted_since_error = accepted
                return pos
            kind = m.lastgroup
            assert kind is not None
            end = m.end()
            value = m.group()
            how = special.get(kind)           # None for most tokens
            if how is not None and how & _IGNORED:
                if how & _NEWLINES and "\n" in value:
                    line += value.count("\n")
                    line_start = pos + value.rindex("\n") + 1
                pos = end
                continue
            tok = new_str(Token, value)           # Token(kind, value, pos, line, ...)
            tok.start_pos = pos
            tok.value = value
            tok.line = line
            tok.column = pos - line_start + 1
            if how is not None:
                if how & _NEWLINES and "\n" in value:
                    line += value.count("\n")
                    line_start = pos + value.rindex("\n") + 1
                if how & _KEYWORDS:
                    kind = keywords[kind].get(value, kind)
                elif how & _SLASH and value == "/" and text.startswith("*", end):
                    # `/*` lexed as an operator: no `*/` follows; do not lex the rest again
                    # at every `/*` in it (that was quadratic)
                    self.accepted_since_error = accepted
                    self._report("E007", "unexpected end of file in a comment: this /* is "
                                 "never closed", self.source.span(pos, pos + 2),
                                 "close the comment with */", always=True)
                    return None
            tok.end_line = line
            tok.end_column = end - line_start + 1
            tok.end_pos = end
            tok.type = kind
            pos = end
            # what ParserState.feed_token does with the token
            while True:
                try:
                    size, arg, goto = actions[state_stack[-1]][kind]
                except KeyError:
                    self.accepted_since_error = accepted
                    self._recover(state, tok, tables.expected(state_stack[-1]))
                    accepted = self.accepted_since_error
                    break
                if size < 0:                          # shift
                    state_stack.append(arg)
                    value_stack.append(tok)
                    accepted += 1
                    accept(tok)
                    break
                if arg is None:                       # `?rule: other`: the value stays
                    below = state_stack[-2]
                    top = units.get((below, state_stack[-1], kind))
                    state_stack[-1] = unit(below, state_stack[-1], kind) if top is None else top
                    continue
                if arg is _APPEND:                    # `x*` goes on: the same tree
                    del state_stack[-size:]
                    value_stack[-size].children += value_stack[1 - size:]
                    del value_stack[1 - size:]
                    state_stack.append(goto[state_stack[-1]])
                    continue
                if size:
                    children = value_stack[-size:]
                    del state_stack[-size:]
                    del value_stack[-size:]
                else:
                    children = []
                value_stack.append(arg(children))
                state_stack.append(goto[state_stack[-1]])
        self.accepted_since_error = accepted
        return None

    def _skip(self, pos: int) -> int:
        """Report the character at `pos`, which starts no token, and skip it: with the rest
        of its line if it opens a string, with the characters after it that start no token
        either (and blanks) otherwise. Returns where the lexer goes on."""
        text = self.source.text
        char = text[pos]
        if char == '"':
            end = text.find("\n", pos)
            end = len(text) if end < 0 else end
            self._report("E006", "unclosed string: no closing '\"' on this line",
                         self.source.span(pos, pos + 1),
                         "a string ends on the line where it starts")
        else:
            end = pos + 1
            starts = _token_start().match
            while end < len(text):
                c = text[end]
                if c == '"' or (c not in _WHITESPACE and starts(text, end) is not None):
                    break
                end += 1
            self._report(
                "E006", f"unexpected character {char!r} ({describe_char(char)})",
                self.source.span(pos, pos + 1), _character_hint(char),
            )
        return end

    def _recover(self, state: ParserState[Any], tok: Token, expected: set[str]) -> None:
        """`tok` cannot follow what the parser has accepted (`expected` can): report it, with
        a hint when the mistake is a known one, and insert the token that lets the parser go
        on (a closer, the unit of a rate, a placeholder), or else drop it."""
        if tok.type in _keyword_terminals() and "NAME" in expected:
            name = Token.new_borrow_pos("NAME", str(tok), tok)
            if self._goes_on(state, name):
                # a reserved word meant as a name: it is read as one
                word = str(tok)
                self._report("E005", f"expected {_expected(expected)}, found the reserved "
                             f"word '{word}'", self._token_span(tok),
                             f"'{word}' is a reserved word{_KEYWORD_ROLES.get(word, '')} and "
                             f"cannot be a name: pick another name, such as '{word}_'")
                state.feed_token(name)
                self.nesting.accept(name)
                return
        explained = self._explain(tok, expected)      # (before _report resets the nesting)
        hint: str | None
        for text, term in self._repairs(expected):
            trial = _trial(state)
            try:
                trial.feed_token(Token(term, text))
                trial.feed_token(tok)
            except Exception:
                continue
            if text in _CLOSERS:
                message, hint = f"missing '{text}' before {_describe(tok)}", f"insert '{text}'"
            elif term == _unit_terminals().get(_UNIT):
                number = self._top_text(state)
                message = f"missing the unit of the rate {number} before {_describe(tok)}"
                hint = f"write the unit after the number: `@ {number} Hz` (or kHz)"
            else:
                message, hint = explained
            self._report("E005", message, self._token_span(tok), hint)
            inserted = Token.new_borrow_pos(term, text, tok)
            try:
                state.feed_token(inserted)
                self.nesting.accept(inserted)
                state.feed_token(tok)
                self.nesting.accept(tok)
            except UnexpectedToken:
                pass  # the repair did not hold on the real stack: the token is dropped
            return
        message, hint = explained
        self._report("E005", message, self._token_span(tok), hint)

    @staticmethod
    def _repairs(expected: set[str]) -> list[tuple[str, str]]:
        """Single tokens worth inserting: closers first, then the unit of a rate, then a
        placeholder name or number."""
        out = [(c, t) for c, t in _closer_terminals().items() if t in expected]
        unit = _unit_terminals().get(_UNIT)
        if unit in expected:
            out.append((_UNIT, unit))
        out += [(v, t) for t, v in (("NAME", "_"), ("INT", "0")) if t in expected]
        return out

    def _explain(self, tok: Token, expected: set[str]) -> tuple[str, str | None]:
        """The message and hint of `tok`, which cannot come here: a hint when the mistake is
        a known one."""
        word = str(tok)
        if tok.type == "IF" and self.nesting.levels[-1].after_operand:
            # (what follows on the line, up to a bound: hostile input makes 1000 errors)
            start = tok.end_pos or 0
            rest = self.source.text[start:start + 200].split("\n", 1)[0]
            if re.search(r"\belse\b", rest):
                # `a if c else b`: Python's conditional
                value = self._expression_text(tok)
                return ("'if' after a value: a conditional expression starts with `if`",
                        f"write `if CONDITION then {value} else OTHER` (not "
                        f"`{value} if CONDITION else OTHER`)")
        units = _unit_terminals()
        if tok.type == "NAME" and units.get(_UNIT) in expected:
            for unit in units:
                if word.lower() == unit.lower():
                    return (f"expected {_expected(expected)}, found {_describe(tok)}",
                            f"the unit of a rate is written `{unit}`")
        return f"expected {_expected(expected)}, found {_describe(tok)}", None

    def _goes_on(self, state: ParserState[Any], tok: Token) -> bool:
        """Whether the parser takes `tok` and then the token after it in the text."""
        trial = _trial(state)
        try:
            trial.feed_token(tok)
            after = self._next_token(tok.end_pos or 0)
            if after is not None:
                trial.feed_token(after)
        except Exception:       # (as the trials of _recover)
            return False
        return True

    def _next_token(self, pos: int) -> Token | None:
        """The token at `pos` or after it, blanks and comments skipped (None at the end of
        the text or before a character that starts no token)."""
        tables = _tables()
        text = self.source.text
        while pos < len(text):
            m = tables.match(text, pos)
            if m is None or m.lastgroup is None:
                return None
            how = tables.special.get(m.lastgroup, 0)
            if not how & _IGNORED:
                kind = m.lastgroup
                if how & _KEYWORDS:
                    kind = tables.keywords[kind].get(m.group(), kind)
                return Token(kind, m.group(), pos, end_pos=m.end())
            pos = m.end()
        return None

    def _expression_text(self, tok: Token) -> str:
        """The text of the expression that ends before `tok` (VALUE where it is long)."""
        start, end = self.nesting.levels[-1].start, tok.start_pos or 0
        text = self.source.text[start:end].strip() if start >= 0 and end - start <= 60 else ""
        return text if text and len(text) <= 40 and "\n" not in text else "VALUE"

    def _top_text(self, state: ParserState[Any]) -> str:
        """The text of the value on top of the parser's stack (a number: `20`)."""
        top = state.value_stack[-1] if state.value_stack else None
        if isinstance(top, Token):
            return _shortened(str(top), 20)
        span = getattr(top, "span", None)
        if isinstance(span, Span):
            return _shortened(self.source.text[span.offset:min(span.end_offset,
                                                              span.offset + 40)], 20)
        return "N"

    def _finish(self, state: ParserState[Any]) -> Any:
        n = len(self.source.text)
        line, column = self.source.position(n)
        end = Token("$END", "", n, line, column, line, column, n)
        inserted: list[str] = []
        for _ in range(4 * MAX_DEPTH):
            trial = _trial(state)
            try:
                tree = trial.feed_token(end, True)
                break
            except UnexpectedToken as e:
                expected = set(e.expected) if e.expected else set()
            # a failed feed may have reduced the trial's stack: try closers on fresh copies
            for closer, term in _closer_terminals().items():
                candidate = _trial(state)
                try:
                    candidate.feed_token(Token.new_borrow_pos(term, closer, end))
                except UnexpectedToken:
                    continue
                state = candidate
                inserted.append(closer)
                break
            else:
                self._report(
                    "E007", f"unexpected end of file: expected {_expected(expected)}",
                    self._token_span(end),
                )
                return None
        else:
            return None
        if inserted:
            self._report(
                "E007", "unexpected end of file: missing " + " ".join(f"'{c}'" for c in inserted),
                self._token_span(end), "close every '{' that is still open",
            )
        return tree


def parse(source: SourceFile) -> ParseResult:
    """Parse one file. Returns the module (None when nothing usable was recovered)."""
    driver = _Driver(source)
    builder = AstBuilder(source)
    building(builder)
    module: ast.Module | None = None
    try:
        result = driver.run()
        if isinstance(result, ast.Module):
            module = result
    except (UnexpectedToken, UnexpectedCharacters, ValueError, KeyError, TypeError):
        # recovery could not rebuild a tree from what was left: the errors stand
        if not driver.diagnostics:
            driver.diagnostics.append(Diagnostic(
                "E005", "the file could not be parsed", source.span(0, 0)))
    except NestingTooDeep as e:
        module = None
        driver.diagnostics.append(Diagnostic(
            "E008", e.message, e.span,
            "split the expression with `let` or an external operation",
        ))
    finally:
        building(None)
    diagnostics = driver.diagnostics + builder.problems()
    diagnostics.sort(key=lambda d: (d.span.offset, d.span.line, d.span.column))
    return ParseResult(module, tuple(diagnostics))
