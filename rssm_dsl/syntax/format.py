"""The canonical formatter (`rssmc fmt`, LSP formatting).

The grammar ignores comments, so the formatter does not print the AST: it re-lexes the text
with the grammar's own lexer, keeping whitespace and comment tokens, and prints the same
tokens again with canonical layout:

- two spaces of indentation per block (`{ ... }` of declarations), one more level for the
  statements of a data-availability case; a line that continues a statement is indented four
  more spaces, or aligned after its open bracket when the bracket is followed by text;
- a line break after a block's `{`, before and after its `}`, after a case label's `:` and
  before every declaration or statement; other line breaks are the writer's;
- except a block written on one line (`enum Cmd { stay, job, charge }`, `update goal
  { goal := x }`, `record Pose { position: Vec3, yaw: float }`, `behaviour b { terminal
  never when false }`): it stays on one line when it holds one declaration, one statement or
  one member list, no comment and no other block, and the line then fits in LINE_LENGTH
  columns (its trailing `//` comment not counted); otherwise it is laid out as above. A block
  written on several lines stays on several lines, so formatting twice changes nothing;
- at most one blank line in a row, none at the start or end of a block or file;
- canonical spacing between tokens (`a := f(x, y)`, `e.lwr`, `-x`, `float[3]`, `{a: 1}`);
- every comment kept, in place; a block comment is copied verbatim; the `//` comments that
  end consecutive lines of code are aligned, two spaces after the longest line.

Only whitespace changes: the output is checked to lex to the same tokens and to parse
without errors, so formatting never changes the meaning (or the IR) of a specification.
"""

from __future__ import annotations

from dataclasses import field, replace
from functools import cache

from lark import Token
from lark.exceptions import LarkError

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.source import SourceFile
from rssm_dsl.syntax.parser import _lark, parse

INDENT = "  "
CONTINUATION = "    "
LINE_LENGTH = 100      # columns a one-line block may reach (what a diagnostic shows of a line)

_COMMENTS = frozenset({"COMMENT", "BLOCK_COMMENT"})
# Keywords that start a declaration or a statement: a line break goes before them.
_DECL_START = frozenset({
    "import", "record", "enum", "type", "const", "extern", "device", "system", "agent", "control",
    "effector", "receptor", "real", "binding", "memory", "param", "input", "output",
    "behaviour", "update", "case", "terminal", "error", "send", "receive", "initial", "switch",
    "let", "skip", "property",
})
# Keywords that can follow another keyword inside one declaration (`device effector`,
# `real receptor`, `update memory`, `switch a -> b otherwise`).
_AFTER = {"effector": {"device", "real"}, "receptor": {"device", "real"}, "memory": {"update"}}
_BLOCK_OPENER_KEYWORDS = frozenset({"memory", "control", "effector", "receptor", "Hz", "kHz"})
_VALUE_TYPES = frozenset({"NAME", "INT", "FLOAT", "STRING"})
_EXPR_END_WORDS = frozenset({")", "]", "true", "false", "skip"})
_NO_SPACE_BEFORE = frozenset({",", ";", ")", "]", ".", ":", ".."})
_NO_SPACE_AFTER = frozenset({"(", "[", ".", ".."})
_OPEN = {"(": ")", "[": "]", "{": "}"}


@cache
def keywords() -> frozenset[str]:
    """The reserved words of the grammar (string terminals made of letters)."""
    return frozenset(
        str(t.pattern.value) for t in _lark().terminals
        if t.pattern.type == "str" and str(t.pattern.value).isalpha()
    )


@dataclass(frozen=True)
class FormatResult:
    text: str | None                       # None: the input has syntax errors
    diagnostics: tuple[Diagnostic, ...] = ()

    @property
    def ok(self) -> bool:
        return self.text is not None


class FormatterBug(Exception):
    """The output would not be the same tokens as the input (never expected)."""


@dataclass
class _Block:
    level: int                 # indentation level of the block's contents
    opener: str | None         # the keyword of the declaration that opened it
    case_body: bool = False    # inside `update ... { case ...: <here> }`
    label_pending: bool = False


@dataclass
class _Bracket:
    close: str
    line_indent: int           # indentation (columns) of the line where it opened
    align: int | None          # column to align continuation lines to, if any


@dataclass
class _OneLine:
    """A block being printed on one line, as it was written: `{` at `start`, `}` at `end`."""
    start: int
    end: int
    first: int                 # the first token after `{` (`end` when the block is empty)


@dataclass
class _Saved:
    """The state before a one-line block's `{`, to print the block again if it does not fit."""
    index: int
    newlines: int
    unary_prev: bool
    lines: int
    trailing: dict[int, str]
    cur: list[str]
    col: int
    line_indent: int
    comment: str | None
    blocks: list[_Block]
    prev: Token | None
    prev_sig: Token | None
    prev_kind: str
    decl_kw: str | None


@dataclass
class _Printer:
    lines: list[str] = field(default_factory=list)
    cur: list[str] = field(default_factory=list)
    col: int = 0
    line_indent: int = 0
    comment: str | None = None              # the trailing // comment of the current line
    trailing: dict[int, str] = field(default_factory=dict)   # line -> its trailing comment

    def _end_line(self) -> None:
        if self.comment is not None:
            self.trailing[len(self.lines)] = self.comment
            self.comment = None
        self.lines.append("".join(self.cur).rstrip())

    def newline(self, blank: bool, indent: int) -> None:
        self._end_line()
        if blank:
            self.lines.append("")
        self.cur = [" " * indent]
        self.col = indent
        self.line_indent = indent

    def trail(self, comment: str) -> None:
        """A // comment after code: aligned with those of the next and previous lines."""
        self.comment = comment

    def put(self, text: str) -> None:
        self.cur.append(text)
        nl = text.rfind("\n")
        self.col = len(text) - nl - 1 if nl >= 0 else self.col + len(text)

    def text(self) -> str:
        self._end_line()
        n = 0
        rows = sorted(self.trailing)
        while n < len(rows):          # runs of consecutive lines with trailing comments
            run = [rows[n]]
            while n + 1 < len(rows) and rows[n + 1] == run[-1] + 1:
                n += 1
                run.append(rows[n])
            n += 1
            width = max(len(self.lines[i].rsplit("\n", 1)[-1]) for i in run)
            for i in run:
                last = len(self.lines[i].rsplit("\n", 1)[-1])
                self.lines[i] += " " * (width - last + 2) + self.trailing[i]
        while self.lines and not self.lines[-1]:
            self.lines.pop()
        return "\n".join(self.lines) + "\n" if self.lines else ""


def _significant(tokens: list[Token]) -> list[tuple[str, str]]:
    return [(t.type, str(t)) for t in tokens if t.type != "WS" and t.type not in _COMMENTS]


def _lex(text: str) -> list[Token]:
    return list(_lark().lex(text, dont_ignore=True))


class _Formatter:
    def __init__(self, tokens: list[Token]) -> None:
        self.tokens = tokens
        self.p = _Printer()
        self.blocks: list[_Block] = []
        self.brackets: list[_Bracket] = []
        self.prev: Token | None = None        # previous token, comments included
        self.prev_sig: Token | None = None    # previous token that is not a comment
        self.prev_kind = ""                   # "block{", "block}", "label:", "lit{", ...
        self.decl_kw: str | None = None       # the keyword that started the declaration
        self.pending_align: _Bracket | None = None  # opened by the previous token
        self.index = 0                        # of the token being printed
        self.one_line: _OneLine | None = None  # the block being printed on one line
        self.saved: _Saved | None = None      # the state before its `{`
        self.relayout = False                 # it cannot stay on one line: print it again
        self.expanded: set[int] = set()       # `{`s (by index) of blocks laid out on lines

    # ------------------------------------------------------------ classification
    def _expr_end(self, tok: Token | None, kind: str) -> bool:
        return tok is not None and (tok.type in _VALUE_TYPES or kind == "lit}"
                                    or str(tok) in _EXPR_END_WORDS)

    def _block_brace(self) -> bool:
        p = self.prev_sig
        if p is None or self.brackets:
            return False
        return p.type == "NAME" or (str(p) in _BLOCK_OPENER_KEYWORDS and p.type != "NAME") \
            or (str(p) == ")" and self.decl_kw == "agent")   # agent Robot(boss: agent) {

    def _is_label(self, tok: Token) -> bool:
        """`case` or an `otherwise` that labels a data-availability case."""
        block = self.blocks[-1] if self.blocks else None
        if block is None or block.opener != "update" or self.brackets:
            return False
        return tok.type != "NAME" and str(tok) in ("case", "otherwise")

    def _decl_start(self, tok: Token) -> bool:
        if self.brackets:
            return False
        value = str(tok)
        if tok.type != "NAME" and value in _DECL_START:
            after = _AFTER.get(value)
            return not (after and self.prev_sig is not None and str(self.prev_sig) in after)
        if self._is_label(tok):
            return True
        if tok.type == "NAME" and self.blocks:
            if self.blocks[-1].opener == "record" and str(self.prev_sig) == ",":
                return True  # the next field of a record
            return self._expr_end(self.prev_sig, self.prev_kind)
        return False

    # ------------------------------------------------------------ layout
    def _base(self, tok: Token) -> int:
        if not self.blocks:
            return 0
        block = self.blocks[-1]
        level = block.level + (1 if block.case_body and not self._is_label(tok) else 0)
        return level * len(INDENT)

    def _indent(self, tok: Token, statement: bool) -> int:
        if self.brackets:
            top = self.brackets[-1]
            if str(tok) == top.close:
                return top.line_indent
            return top.align if top.align is not None else top.line_indent + len(CONTINUATION)
        if str(tok) == "}" and self.blocks:
            return (self.blocks[-1].level - 1) * len(INDENT)
        base = self._base(tok)
        if statement or tok.type in _COMMENTS:
            return base
        return base + len(CONTINUATION)

    def _space(self, tok: Token, unary_prev: bool) -> str:
        p = self.prev
        if p is None:
            return ""
        pv, tv = str(p), str(tok)
        if p.type in _COMMENTS or tok.type in _COMMENTS:
            return " "
        if tv in _NO_SPACE_BEFORE and tok.type != "STRING":
            return ""
        if pv in _NO_SPACE_AFTER and p.type not in ("STRING",):
            return ""
        if unary_prev:
            return ""
        if self.prev_kind == "lit{" or (tv == "}" and not self._closing_block(tok)):
            return ""
        if tv == "(":
            return "" if p.type == "NAME" else " "
        if tv == "[":
            return "" if self._expr_end(p, self.prev_kind) else " "
        return " "

    def _closing_block(self, tok: Token) -> bool:
        return str(tok) == "}" and not (self.brackets and self.brackets[-1].close == "}")

    # ------------------------------------------------------------ the loop
    def run(self) -> str:
        newlines = 0
        unary_prev = False
        i = 0
        while i < len(self.tokens):
            tok = self.tokens[i]
            if tok.type == "WS":
                newlines += str(tok).count("\n")
                i += 1
                continue
            if (self.one_line is None and str(tok) == "{" and i not in self.expanded
                    and self._block_brace()):
                self._start_one_line(i, newlines, unary_prev)
            self.index = i
            unary_prev = self._emit(tok, newlines, unary_prev)
            newlines = 0
            if self.one_line is not None:
                if self.relayout or self.p.col > LINE_LENGTH:
                    i, newlines, unary_prev = self._restore()
                    continue
                if i == self.one_line.end:
                    self.one_line = self.saved = None
            i += 1
        return self.p.text()

    # ------------------------------------------------------------ one-line blocks
    def _one_line_end(self, start: int) -> int | None:
        """The index of the `}` closing the block opened at `start`, if the block is written
        on one line without comments; None otherwise."""
        depth = 0
        for j in range(start + 1, len(self.tokens)):
            tok = self.tokens[j]
            value = str(tok)
            if tok.type in _COMMENTS or (tok.type == "WS" and "\n" in value):
                return None
            if value == "{":
                depth += 1
            elif value == "}":
                if depth == 0:
                    return j
                depth -= 1
        return None

    def _start_one_line(self, start: int, newlines: int, unary_prev: bool) -> None:
        end = self._one_line_end(start)
        if end is None:
            return
        first = next(j for j in range(start + 1, end + 1) if self.tokens[j].type != "WS")
        self.one_line = _OneLine(start, end, first)
        p = self.p
        self.saved = _Saved(
            start, newlines, unary_prev, len(p.lines), dict(p.trailing), list(p.cur), p.col,
            p.line_indent, p.comment, [replace(b) for b in self.blocks], self.prev,
            self.prev_sig, self.prev_kind, self.decl_kw)

    def _restore(self) -> tuple[int, int, bool]:
        """Back to the block's `{`, to lay the block out on lines."""
        s = self.saved
        assert s is not None
        p = self.p
        del p.lines[s.lines:]
        p.trailing, p.cur, p.col, p.line_indent, p.comment = (
            s.trailing, s.cur, s.col, s.line_indent, s.comment)
        self.blocks, self.brackets, self.pending_align = s.blocks, [], None
        self.prev, self.prev_sig, self.prev_kind, self.decl_kw = (
            s.prev, s.prev_sig, s.prev_kind, s.decl_kw)
        self.expanded.add(s.index)
        self.one_line = self.saved = None
        self.relayout = False
        return s.index, s.newlines, s.unary_prev

    def _keep_on_line(self, tok: Token) -> bool:
        """Inside a one-line block, a line break the layout would force is dropped: the one
        after `{`, the one before `}`, those before a record's fields. Any other (a second
        statement, a case label, a nested block) means the block is laid out on lines."""
        block = self.one_line
        if block is None or not block.start < self.index <= block.end:
            return False
        if self.index in (block.first, block.end) or (
                tok.type == "NAME" and bool(self.blocks) and self.blocks[-1].opener == "record"
                and str(self.prev_sig) == ","):
            return True
        self.relayout = True
        return True

    def _emit(self, tok: Token, newlines: int, unary_prev: bool) -> bool:
        value = str(tok)
        closing_block = self._closing_block(tok)
        forced = False
        if self.prev is not None:
            if self.prev.type == "COMMENT":
                forced = True
            elif tok.type in _COMMENTS and newlines == 0:
                forced = False
            else:
                forced = (self.prev_kind in ("block{", "block}", "label:") or closing_block
                          or self._decl_start(tok))
            if forced and self._keep_on_line(tok):
                forced = False
        if self.prev is not None and (forced or newlines > 0):
            statement = forced or self.prev_kind in ("block{", "block}", "label:") or (
                bool(self.blocks) and self.blocks[-1].opener == "enum" and not self.brackets)
            blank = (newlines >= 2 and self.prev_kind != "block{" and not closing_block)
            self.p.newline(blank, self._indent(tok, statement))
        elif self.prev is not None:
            if tok.type == "COMMENT":
                self.pending_align = None
                self.p.trail(value)
                return self._after(tok, unary_prev)
            self.p.put(self._space(tok, unary_prev))
            if self.pending_align is not None and tok.type not in _COMMENTS:
                self.pending_align.align = self.p.col
        self.pending_align = None
        self.p.put(value)
        return self._after(tok, unary_prev)

    def _after(self, tok: Token, unary_prev: bool) -> bool:
        """Update the state after printing `tok`; returns whether it is a unary minus."""
        value = str(tok)
        kind = ""
        unary = False
        if tok.type in _COMMENTS:
            self.prev = tok
            return False
        if value in _DECL_START and tok.type != "NAME" and not self.brackets and not (
                value in _AFTER and self.prev_sig is not None
                and str(self.prev_sig) in _AFTER[value]):
            self.decl_kw = value
        block = self.blocks[-1] if self.blocks else None
        if block is not None and self._is_label(tok):
            block.label_pending = True
        if value == "{" and self._block_brace():
            level = self.blocks[-1].level + 1 if self.blocks else 1
            if self.blocks and self.blocks[-1].case_body:
                level += 1
            self.blocks.append(_Block(level, self.decl_kw))
            kind = "block{"
        elif value == "}" and self._closing_block(tok):
            if self.blocks:
                self.blocks.pop()
            kind = "block}"
        elif value in _OPEN:
            # aligned after the bracket only if text follows it on the same line
            self.pending_align = _Bracket(_OPEN[value], self.p.line_indent, None)
            self.brackets.append(self.pending_align)
            kind = "lit{" if value == "{" else "open"
        elif self.brackets and value == self.brackets[-1].close:
            self.brackets.pop()
            kind = "lit}" if value == "}" else "close"
        elif value == ":" and block is not None and block.label_pending and not self.brackets:
            block.label_pending = False
            block.case_body = True
            kind = "label:"
        elif value == "-" and not self._expr_end(self.prev_sig, self.prev_kind):
            unary = True
        self.prev = tok
        self.prev_sig = tok
        self.prev_kind = kind
        return unary


def format_text(text: str, path: str = "<input>") -> FormatResult:
    """Format RSSM source text. Returns FormatResult(None, diagnostics) when the text has
    syntax errors (nothing is formatted then)."""
    source = SourceFile(path, text)
    result = parse(source)
    if result.diagnostics or result.module is None:
        return FormatResult(None, result.diagnostics)
    try:
        tokens = _lex(source.text)      # bare CRs are line ends, as the parser read them
    except LarkError:  # the parser accepted it, so the lexer does too; be safe anyway
        return FormatResult(None, result.diagnostics)
    formatted = _Formatter(tokens).run()
    if _significant(_lex(formatted)) != _significant(tokens):
        raise FormatterBug("formatting changed the tokens")
    if parse(SourceFile(path, formatted)).diagnostics:
        raise FormatterBug("formatted text does not parse")
    return FormatResult(formatted)
