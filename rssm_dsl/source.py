"""Source files and spans: every AST node, IR element and diagnostic points back to the text.

Lines. The line terminators of RSSM are exactly ``\\n``, ``\\r\\n`` and a bare ``\\r`` (the set
the Language Server Protocol defines); U+2028, U+2029, U+0085, ``\\v``, ``\\f`` and
``\\x1c``-``\\x1e`` are ordinary characters (``str.splitlines`` splits on all of them: it is
never used on source text). :func:`line_starts` and :func:`split_lines` are the one definition
of lines: the diagnostics, the HTML explorer and the language server use them.

The lexer (Lark) counts lines by ``\\n`` alone, so :class:`SourceFile` keeps its text with
every bare ``\\r`` replaced by ``\\n`` (:func:`lexer_text`): the same length, so offsets,
lines and columns are those of the file as written.
"""

from __future__ import annotations

import bisect
import re
import unicodedata
from dataclasses import field

from rssm_core.records import dataclass

_BARE_CR = re.compile(r"\r(?!\n)")

# The most the compiler reads as one piece of text: a spec file (rssm_dsl/semantics/loader.py,
# E004), and one line of a trace or one JSON document given to `simulate --replay` or
# `render --trace` (rssm_dsl/interp/trace.py, E852). Nothing larger is ever held whole.
MAX_FILE_BYTES = 8 * 1024 * 1024


def lexer_text(text: str) -> str:
    """``text`` with every bare CR (one not followed by LF) replaced by LF. The result has the
    same length and the same lines: only ``\\n`` and ``\\r\\n`` end lines in it."""
    return _BARE_CR.sub("\n", text) if "\r" in text else text


def _starts(text: str) -> list[int]:
    """Line starts of a text whose only terminators are LF and CRLF."""
    starts = [0]
    find = text.find
    i = find("\n")
    while i >= 0:  # str.find runs in C: much faster than a loop over every character
        starts.append(i + 1)
        i = find("\n", i + 1)
    return starts


def line_starts(text: str) -> list[int]:
    """The 0-based offset at which each line of ``text`` begins: 0, then the offset after
    every line terminator (``\\n``, ``\\r\\n`` or a bare ``\\r``). A text with n terminators
    has n + 1 lines; the last is empty when the text ends with a terminator."""
    return _starts(lexer_text(text))


# The characters at which str.splitlines breaks lines that do not end an RSSM line.
NOT_LINE_BREAKS = "\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"


def split_lines(text: str) -> list[str]:
    """The lines of ``text`` without their terminators (``\\n``, ``\\r\\n``, bare ``\\r``):
    ``len(split_lines(t)) == len(line_starts(t))``, so ``"a\\n"`` gives ``["a", ""]``
    (``str.splitlines`` gives ``["a"]`` and also splits on U+2028 and other characters that
    do not end an RSSM line)."""
    return lexer_text(text).replace("\r\n", "\n").split("\n")


# Characters shown escaped wherever source text is printed (excerpts, quoted names): the C0
# controls but tab, DEL, the C1 controls, the bidirectional controls that reorder what a
# terminal shows (U+202A-U+202E, U+2066-U+2069, also U+200E/U+200F/U+061C) and the Unicode
# line and paragraph separators. A spec file must never send a terminal an escape sequence.
_UNSAFE = re.compile(
    "[\x00-\x08\x0a-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def _escape_char(ch: str) -> str:
    n = ord(ch)
    return f"\\x{n:02x}" if n < 0x100 else f"\\u{n:04x}"


def escape_char(ch: str) -> str:
    """How one character is shown in printed source text: itself, or escaped (``\\x07``,
    ``\\u202e``) when it is a control character (see :func:`escape_controls`)."""
    return _escape_char(ch) if _UNSAFE.match(ch) else ch


def escape_controls(text: str) -> str:
    """``text`` with every control character escaped (``\\x1b``, ``\\u202e``); tabs kept."""
    return _UNSAFE.sub(lambda m: _escape_char(m.group()), text)


def describe_char(ch: str) -> str:
    """``U+2028 LINE SEPARATOR``: a character's code point and Unicode name (the name of a
    control character, which has none, is left out)."""
    name = unicodedata.name(ch, "")
    return f"U+{ord(ch):04X} {name}" if name else f"U+{ord(ch):04X}"


@dataclass(frozen=True, slots=True)
class Span:
    """A region of one source file. Lines and columns are 1-based; offsets are 0-based."""

    file: str
    line: int
    column: int
    end_line: int
    end_column: int
    offset: int = 0
    end_offset: int = 0

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"

    @property
    def location(self) -> str:
        return f"{self.file}:{self.line}"

    def to(self, other: Span) -> Span:
        """The span from the start of self to the end of other (same file)."""
        return Span(
            self.file, self.line, self.column, other.end_line, other.end_column,
            self.offset, other.end_offset,
        )


@dataclass(frozen=True)
class SourceFile:
    """The text of one file, with a line index for offset -> (line, column) conversion.

    ``text`` is the text as the lexer reads it: bare CRs are LFs (:func:`lexer_text`), so the
    parser, the line index and the excerpts agree on lines whatever the file's line ends."""

    path: str
    text: str
    _line_starts: tuple[int, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        text = lexer_text(self.text)
        object.__setattr__(self, "text", text)
        object.__setattr__(self, "_line_starts", tuple(_starts(text)))

    @property
    def line_count(self) -> int:
        return len(self._line_starts)

    def position(self, offset: int) -> tuple[int, int]:
        """1-based (line, column) of a 0-based offset."""
        offset = max(0, min(offset, len(self.text)))
        line = bisect.bisect_right(self._line_starts, offset) - 1
        return line + 1, offset - self._line_starts[line] + 1

    def span(self, start: int, end: int) -> Span:
        line, col = self.position(start)
        end_line, end_col = self.position(end)
        return Span(self.path, line, col, end_line, end_col, start, end)

    def line_text(self, line: int) -> str:
        """The text of a 1-based line, without its terminator ("" past the end)."""
        if line < 1 or line > len(self._line_starts):
            return ""
        start = self._line_starts[line - 1]
        if line == len(self._line_starts):
            return self.text[start:]
        end = self._line_starts[line] - 1          # the LF
        if end > start and self.text[end - 1] == "\r":
            end -= 1                               # CRLF
        return self.text[start:end]


def file_kind(mode: int) -> str:
    """What a file that is not a regular file is, as an aside of a message: " (a FIFO)";
    empty for a regular file (``mode``: ``os.stat(...).st_mode``)."""
    import stat

    for test, what in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return f" ({what})"
    return ""
