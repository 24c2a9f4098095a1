"""Positions: the compiler counts code-point offsets (and 1-based lines and columns); LSP
counts 0-based lines and characters in the encoding the client negotiated (UTF-16 unless told
otherwise).

Line terminators are exactly those of the LSP specification: `\\n`, `\\r\\n` and a bare `\\r`
(`rssm_dsl.source.line_starts`, the compiler's one definition of lines). U+2028, U+2029 and
U+0085 are ordinary characters (one UTF-16 unit each), unlike for `str.splitlines()`, which
must not be used on a document's text.

Compiler spans are converted through their code-point offsets (not their line and column), so
that positions do not depend on how the compiler counts lines. Conversions stay fast on a
1 MB line: a line's characters wider than one code unit are tabulated once (per encoding) and
every conversion on it is a binary search.
"""

from __future__ import annotations

import bisect
import re
from dataclasses import field

from lsprotocol import types as lsp

from rssm_core.records import dataclass
from rssm_dsl.source import Span, line_starts

UTF8, UTF16, UTF32 = "utf-8", "utf-16", "utf-32"
BOM = "\ufeff"
_WIDE = {UTF16: re.compile("[\U00010000-\U0010ffff]"), UTF8: re.compile("[^\x00-\x7f]")}


def line_start(text: str, offset: int) -> int:
    """The offset of the start of the line holding `offset`."""
    return max(text.rfind("\n", 0, offset), text.rfind("\r", 0, offset)) + 1


def line_end(text: str, offset: int) -> int:
    """The offset of the line terminator at or after `offset` (len(text) when none)."""
    ends = [i for i in (text.find("\n", offset), text.find("\r", offset)) if i >= 0]
    return min(ends) if ends else len(text)


def _line_ends(text: str, starts: list[int]) -> list[int]:
    """Where each line's terminator begins (len(text) for the last line)."""
    if "\r" not in text:
        ends = [s - 1 for s in starts[1:]]
    else:
        ends = [s - (2 if s >= 2 and text.startswith("\r\n", s - 2) else 1)
                for s in starts[1:]]
    ends.append(len(text))
    return ends


def split_lines(text: str, keepends: bool = False) -> list[str]:
    """The lines of `text`, split on exactly `\\n`, `\\r\\n` and `\\r` (like
    `str.splitlines`, which also splits on U+2028 and others; no empty last line)."""
    starts = line_starts(text)
    stops = [*starts[1:], len(text)] if keepends else _line_ends(text, starts)
    out = [text[a:b] for a, b in zip(starts, stops, strict=True)]
    return out[:-1] if out and starts[-1] == len(text) else out


def count_lines(text: str) -> int:
    """The number of lines of `text` (one more than its line terminators)."""
    if "\r" not in text:
        return text.count("\n") + 1    # the same, counted in C
    return len(line_starts(text))


def _char_units(ch: str, encoding: str) -> int:
    if encoding == UTF8:
        return len(ch.encode("utf-8", "surrogatepass"))
    return 2 if encoding == UTF16 and ord(ch) > 0xFFFF else 1


def units(text: str, encoding: str) -> int:
    """The length of `text` in code units of `encoding`."""
    if encoding == UTF32 or text.isascii():
        return len(text)
    if encoding == UTF8:
        return len(text.encode("utf-8", "surrogatepass"))
    return len(text) + sum(1 for ch in text if ord(ch) > 0xFFFF)


@dataclass(frozen=True)
class _Wide:
    """The characters of one line wider than one code unit: their columns (ascending) and
    the extra units of all of them up to and including each."""

    columns: tuple[int, ...]
    extra: tuple[int, ...]

    @staticmethod
    def of(line: str, encoding: str) -> _Wide:
        pattern = _WIDE.get(encoding)
        if pattern is None or line.isascii():
            return _Wide((), ())
        columns: list[int] = []
        extra: list[int] = []
        total = 0
        for m in pattern.finditer(line):
            columns.append(m.start())
            total += _char_units(m.group(), encoding) - 1
            extra.append(total)
        return _Wide(tuple(columns), tuple(extra))

    def units(self, column: int) -> int:
        """The code units of the first `column` code points of the line."""
        k = bisect.bisect_left(self.columns, column)
        return column + (self.extra[k - 1] if k else 0)

    def column(self, character: int, length: int) -> int:
        """The first column whose code units reach `character` (clamped to the line)."""
        if character <= 0:
            return 0
        if not self.columns:
            return min(character, length)
        lo, hi = 0, length
        while lo < hi:
            mid = (lo + hi) // 2
            if self.units(mid) >= character:
                hi = mid
            else:
                lo = mid + 1
        return lo


def column_of(line: str, character: int, encoding: str) -> int:
    """The code-point column (0-based) of an LSP character offset in `line`; clamped."""
    return _Wide.of(line, encoding).column(character, len(line))


@dataclass(frozen=True)
class LineIndex:
    """The lines of one text, for conversions in both directions."""

    text: str
    starts: tuple[int, ...] = field(init=False, repr=False)
    ends: tuple[int, ...] = field(init=False, repr=False)       # before the terminator
    bom: int = field(init=False, repr=False)   # compiler offsets count from after a BOM
    _wide: dict[tuple[int, str], _Wide] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        starts = line_starts(self.text)
        object.__setattr__(self, "starts", tuple(starts))
        object.__setattr__(self, "ends", tuple(_line_ends(self.text, starts)))
        object.__setattr__(self, "bom", 1 if self.text.startswith(BOM) else 0)
        object.__setattr__(self, "_wide", {})

    def line(self, n: int) -> str:
        """Line n (0-based) without its line terminator; '' out of range."""
        if n < 0 or n >= len(self.starts):
            return ""
        return self.text[self.starts[n]:self.ends[n]]

    def _table(self, n: int, encoding: str) -> _Wide:
        key = (n, encoding)
        table = self._wide.get(key)
        if table is None:
            table = self._wide[key] = _Wide.of(self.line(n), encoding)
        return table

    def offset(self, pos: lsp.Position, encoding: str) -> int:
        """The code-point offset of an LSP position, clamped into the text."""
        if pos.line < 0:
            return 0
        if pos.line >= len(self.starts):
            return len(self.text)
        n = pos.line
        length = self.ends[n] - self.starts[n]
        return self.starts[n] + self._table(n, encoding).column(pos.character, length)

    def spot(self, offset: int, encoding: str) -> tuple[int, int]:
        """The (line, character) of a code-point offset, clamped into the text."""
        offset = max(0, min(offset, len(self.text)))
        n = bisect.bisect_right(self.starts, offset) - 1
        col = min(offset, self.ends[n]) - self.starts[n]
        return n, self._table(n, encoding).units(col)

    def position(self, offset: int, encoding: str) -> lsp.Position:
        line, character = self.spot(offset, encoding)
        return lsp.Position(line=line, character=character)

    def _point(self, line: int, column: int, encoding: str) -> tuple[int, int]:
        n = max(0, min(line - 1, len(self.starts) - 1))
        col = max(0, min(column - 1, self.ends[n] - self.starts[n]))
        return n, self._table(n, encoding).units(col)

    def point(self, line: int, column: int, encoding: str) -> lsp.Position:
        """An LSP position from a compiler (1-based line, 1-based code-point column)."""
        n, character = self._point(line, column, encoding)
        return lsp.Position(line=n, character=character)

    def ends_of(self, span: Span, encoding: str) -> tuple[tuple[int, int], tuple[int, int]]:
        """The (line, character) where a span starts and ends."""
        if span.offset == 0 and span.end_offset == 0 and (span.line, span.column) != (1, 1):
            # a span made without offsets: its line and column are all there is
            start = self._point(span.line, span.column, encoding)
            end = self._point(span.end_line, span.end_column, encoding)
        else:
            start = self.spot(span.offset + self.bom, encoding)
            end = self.spot(max(span.offset, span.end_offset) + self.bom, encoding)
        return start, max(start, end)

    def range(self, span: Span, encoding: str) -> lsp.Range:
        (l0, c0), (l1, c1) = self.ends_of(span, encoding)
        return lsp.Range(start=lsp.Position(line=l0, character=c0),
                         end=lsp.Position(line=l1, character=c1))

    def whole(self, encoding: str) -> lsp.Range:
        """The range of the whole text."""
        return lsp.Range(start=lsp.Position(line=0, character=0),
                         end=self.position(len(self.text), encoding))
