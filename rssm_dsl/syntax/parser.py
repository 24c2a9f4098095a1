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
from dataclasses import dataclass
from functools import cache
from typing import Any

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedToken
from lark.parsers.lalr_interactive_parser import InteractiveParser
from lark.parsers.lalr_parser_state import ParserState

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

    __slots__ = ("after_operand", "ifs", "ops", "start")

    def __init__(self) -> None:
        self.after_operand = False
        # the operators of the chain not yet combined, as precedence climbing (build.py)
        # holds them: (is_prefix, precedence, depth of the left operand)
        self.ops: list[tuple[bool, int, int]] = []
        self.ifs: list[int] = []          # the `if`s around the chain, innermost last
        self.start = -1                   # offset of the expression's first token

    def reset(self) -> None:
        self.after_operand = False
        self.ops.clear()
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
            self._binary(level, BINARY_PRECEDENCE[str(tok)], tok)
        elif role in (_MINUS, _NOT):
            if level.after_operand:
                level.reset()
            if level.start < 0:
                level.start = tok.start_pos or 0
            level.ops.append((True, PREFIX_PRECEDENCE[str(tok)], 0))
            self._check(level, tok)
        elif role == _POSTFIX:
            level.after_operand = False   # `a.b`, `a in b`: the name follows
        elif role in (_OPEN, _CLOSE):
            self._bracket(level, role, tok)
        else:
            self._if(level, role, tok)

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

    def _binary(self, level: _Level, prec: int, tok: Token) -> None:
        ops = level.ops
        cur = 0
        while ops:
            is_prefix, p, left = ops[-1]
            if p < prec or (p == prec and is_prefix):
                break
            ops.pop()
            cur = 1 + (cur if is_prefix else max(left, cur))
        ops.append((False, prec, cur))
        level.after_operand = False
        self._check(level, tok)

    def _if(self, level: _Level, role: int, tok: Token) -> None:
        ifs = level.ifs
        level.ops.clear()
        level.after_operand = False
        if role == _IF:
            if level.start < 0:
                level.start = tok.start_pos or 0
            ifs.append(_IF_CONDITION)
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
        ip = _lark().parse_interactive(self.source.text)
        state = ip.parser_state
        try:
            while True:
                try:
                    self._read(ip, state)
                    break
                except UnexpectedCharacters as e:
                    self._skip(ip, e.pos_in_stream or 0)
            return self._finish(state)
        except _Stop as stop:
            self.diagnostics.append(Diagnostic(
                "E005", "too many syntax errors: the parse stops here", stop.span,
                "fix the errors above and check again (the rest of the file is not read "
                f"after {MAX_ERRORS} errors)"))
            return None

    def _read(self, ip: InteractiveParser, state: ParserState[Any]) -> None:
        """Feed the tokens to the parser until the end of the file or an unclosed block
        comment (reported). Raises UnexpectedCharacters where no token starts."""
        text = self.source.text
        feed = state.feed_token
        accept = self.nesting.accept
        for tok in ip.lexer_thread.lex(state):
            if tok.type == "BINOP" and tok == "/" and text.startswith("*", tok.end_pos):
                # `/*` lexed as an operator: no `*/` follows; do not lex the rest again
                # at every `/*` in it (that was quadratic)
                start = tok.start_pos or 0
                self._report("E007", "unexpected end of file in a comment: this /* is "
                             "never closed", self.source.span(start, start + 2),
                             "close the comment with */", always=True)
                return
            try:
                feed(tok)
            except UnexpectedToken as e:
                self._recover(state, tok, e)
                continue
            self.accepted_since_error += 1
            accept(tok)

    def _skip(self, ip: InteractiveParser, pos: int) -> None:
        """Report the character at `pos`, which starts no token, and skip it: with the rest
        of its line if it opens a string, with the characters after it that start no token
        either (and blanks) otherwise."""
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
        lexer_state = ip.lexer_thread.state
        assert lexer_state is not None
        lexer_state.line_ctr.feed(text[pos:end])

    def _recover(self, state: ParserState[Any], tok: Token, e: UnexpectedToken) -> None:
        expected = set(e.expected) if e.expected else set()
        for text, term in self._repairs(expected):
            trial = _trial(state)
            try:
                trial.feed_token(Token(term, text))
                trial.feed_token(tok)
            except Exception:
                continue
            if text in _CLOSERS:
                message, hint = f"missing '{text}' before {_describe(tok)}", f"insert '{text}'"
            else:
                message, hint = f"expected {_expected(expected)}, found {_describe(tok)}", None
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
        self._report(
            "E005", f"expected {_expected(expected)}, found {_describe(tok)}",
            self._token_span(tok),
        )

    @staticmethod
    def _repairs(expected: set[str]) -> list[tuple[str, str]]:
        """Single tokens worth inserting: closers first, then a placeholder name or number."""
        out = [(c, t) for c, t in _closer_terminals().items() if t in expected]
        out += [(v, t) for t, v in (("NAME", "_"), ("INT", "0")) if t in expected]
        return out

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
