"""Positions: the compiler counts 1-based lines and columns in code points; LSP counts 0-based
lines and characters in the encoding the client negotiated (UTF-16 unless told otherwise)."""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field

from lsprotocol import types as lsp

from rssm_dsl.source import Span

UTF8, UTF16, UTF32 = "utf-8", "utf-16", "utf-32"


def units(text: str, encoding: str) -> int:
    """The length of `text` in code units of `encoding`."""
    if encoding == UTF32 or text.isascii():
        return len(text)
    if encoding == UTF8:
        return len(text.encode("utf-8", "surrogatepass"))
    return len(text) + sum(1 for ch in text if ord(ch) > 0xFFFF)


def column_of(line: str, character: int, encoding: str) -> int:
    """The code-point column (0-based) of an LSP character offset in `line`; clamped."""
    if character <= 0:
        return 0
    if encoding == UTF32 or line.isascii():
        return min(character, len(line))
    count = 0
    for i, ch in enumerate(line):
        if count >= character:
            return i
        count += units(ch, encoding)
    return len(line)


@dataclass(frozen=True)
class LineIndex:
    """The lines of one text, for conversions in both directions."""

    text: str
    starts: tuple[int, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        starts = [0]
        find = self.text.find
        i = find("\n")
        while i >= 0:
            starts.append(i + 1)
            i = find("\n", i + 1)
        object.__setattr__(self, "starts", tuple(starts))

    def line(self, n: int) -> str:
        """Line n (0-based) without its line break; '' out of range."""
        if n < 0 or n >= len(self.starts):
            return ""
        start = self.starts[n]
        end = self.starts[n + 1] - 1 if n + 1 < len(self.starts) else len(self.text)
        return self.text[start:end].removesuffix("\r")

    def offset(self, pos: lsp.Position, encoding: str) -> int:
        """The code-point offset of an LSP position, clamped into the text."""
        if pos.line < 0:
            return 0
        if pos.line >= len(self.starts):
            return len(self.text)
        return self.starts[pos.line] + column_of(self.line(pos.line), pos.character, encoding)

    def position(self, offset: int, encoding: str) -> lsp.Position:
        offset = max(0, min(offset, len(self.text)))
        n = bisect.bisect_right(self.starts, offset) - 1
        line = self.line(n)
        col = min(offset - self.starts[n], len(line))
        return lsp.Position(line=n, character=units(line[:col], encoding))

    def point(self, line: int, column: int, encoding: str) -> lsp.Position:
        """An LSP position from a compiler (1-based line, 1-based code-point column)."""
        n = max(0, min(line - 1, len(self.starts) - 1))
        text = self.line(n)
        col = max(0, min(column - 1, len(text)))
        return lsp.Position(line=n, character=units(text[:col], encoding))

    def range(self, span: Span, encoding: str) -> lsp.Range:
        start = self.point(span.line, span.column, encoding)
        end = self.point(span.end_line, span.end_column, encoding)
        if (end.line, end.character) < (start.line, start.character):
            end = start
        return lsp.Range(start=start, end=end)

    def whole(self, encoding: str) -> lsp.Range:
        """The range of the whole text."""
        return lsp.Range(start=lsp.Position(line=0, character=0),
                         end=self.position(len(self.text), encoding))
