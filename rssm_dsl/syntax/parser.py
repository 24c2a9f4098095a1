"""Parse RSSM text into an AST, reporting several syntax errors per run.

Lark's LALR parser is driven token by token so that an error does not end the parse:
a missing closer (`}`, `)`, `]`, `:`) is inserted when that lets the parser go on,
otherwise the offending token is dropped. Errors closer than three accepted tokens to the
previous one are not reported (they are almost always echoes of it).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Any

from lark import Lark, Token
from lark.exceptions import UnexpectedCharacters, UnexpectedToken
from lark.parsers.lalr_interactive_parser import InteractiveParser

from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.resources import grammar_text
from rssm_dsl.source import SourceFile, Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.build import AstBuilder, Callbacks, NestingTooDeep, building

MAX_ERRORS = 25
_CLOSERS = ("}", ")", "]", ":")


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
        return f"name '{tok.value}'"
    if tok.type in ("INT", "FLOAT"):
        return f"number {tok.value}"
    if tok.type == "STRING":
        return f"string {tok.value}"
    return f"'{tok.value}'"


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
    if char.isspace():
        return "replace it with an ordinary space"
    return "remove it; names are ASCII letters, digits and '_'"


class _Driver:
    def __init__(self, source: SourceFile) -> None:
        self.source = source
        self.diagnostics: list[Diagnostic] = []
        self.accepted_since_error = 1_000_000

    # -- reporting
    def _report(self, code: str, message: str, span: Span, hint: str | None = None) -> None:
        if self.accepted_since_error >= 3 and len(self.diagnostics) < MAX_ERRORS:
            self.diagnostics.append(Diagnostic(code, message, span, hint))
        self.accepted_since_error = 0

    def _token_span(self, tok: Token) -> Span:
        start = tok.start_pos if tok.start_pos is not None else len(self.source.text)
        end = tok.end_pos if tok.end_pos is not None else start
        if tok.type == "$END":
            start = end = len(self.source.text)
        return self.source.span(start, max(end, start))

    # -- the loop
    def run(self) -> Any:
        ip = _lark().parse_interactive(self.source.text)
        while True:
            try:
                for tok in ip.lexer_thread.lex(ip.parser_state):
                    self._feed(ip, tok)
                break
            except UnexpectedToken as e:
                # the contextual lexer found a token this state does not accept
                self._feed(ip, e.token)
            except UnexpectedCharacters as e:
                pos = e.pos_in_stream or 0
                char = self.source.text[pos]
                self._report(
                    "E006", f"unexpected character {char!r} (U+{ord(char):04X})",
                    self.source.span(pos, pos + 1), _character_hint(char),
                )
                state = ip.lexer_thread.state
                assert state is not None
                state.line_ctr.feed(self.source.text[pos : pos + 1])
        return self._finish(ip)

    def _feed(self, ip: InteractiveParser, tok: Token) -> None:
        try:
            ip.feed_token(tok)
            self.accepted_since_error += 1
            return
        except UnexpectedToken as e:
            expected = set(e.expected) if e.expected else set()
        for text, term in self._repairs(expected):
            trial = ip.copy(deepcopy_values=False)
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
            try:
                ip.feed_token(Token.new_borrow_pos(term, text, tok))
                ip.feed_token(tok)
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

    def _finish(self, ip: InteractiveParser) -> Any:
        n = len(self.source.text)
        line, column = self.source.position(n)
        end = Token("$END", "", n, line, column, line, column, n)
        inserted: list[str] = []
        for _ in range(200):
            trial = ip.copy(deepcopy_values=False)
            try:
                tree = trial.feed_eof()
                break
            except UnexpectedToken as e:
                expected = set(e.expected) if e.expected else set()
            # a failed feed may have reduced the trial's stack: try closers on fresh copies
            for closer, term in _closer_terminals().items():
                candidate = ip.copy(deepcopy_values=False)
                try:
                    candidate.feed_token(Token.new_borrow_pos(term, closer, end))
                except UnexpectedToken:
                    continue
                ip = candidate
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
    building(AstBuilder(source))
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
        driver.diagnostics.append(Diagnostic(
            "E008", f"nesting deeper than {e.limit} levels", e.span,
            "split the expression with `let` or an external operation",
        ))
    finally:
        building(None)  # type: ignore[arg-type]
    return ParseResult(module, tuple(driver.diagnostics))
