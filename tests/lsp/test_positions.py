"""Positions (rssm_dsl/lsp/positions.py) and the documents' texts (documents.py): lines end at
exactly `\\n`, `\\r\\n` and `\\r`; U+2028, U+2029 and U+0085 are ordinary characters."""

from __future__ import annotations

import time

import pytest
from hypothesis import given
from hypothesis import strategies as st
from lsprotocol import types as lsp

from rssm_dsl import source
from rssm_dsl.lsp.documents import LspLinesDocument
from rssm_dsl.lsp.positions import (
    UTF8,
    UTF16,
    UTF32,
    LineIndex,
    count_lines,
    line_end,
    line_start,
    split_lines,
    units,
)
from rssm_dsl.source import Span

ODD = "\u2028\u2029\u0085\x0b\x0c\x1c"   # str.splitlines() breaks at all of these


def pos(line: int, character: int) -> lsp.Position:
    return lsp.Position(line=line, character=character)


def test_the_three_line_terminators_and_no_other() -> None:
    text = f"a\nb\r\nc\rd{ODD}e\n"
    assert split_lines(text) == ["a", "b", "c", f"d{ODD}e"]
    assert split_lines(text, keepends=True) == ["a\n", "b\r\n", "c\r", f"d{ODD}e\n"]
    assert count_lines(text) == 5
    lines = LineIndex(text)
    assert [lines.line(n) for n in range(5)] == ["a", "b", "c", f"d{ODD}e", ""]
    at_e = text.index("e")
    assert lines.position(at_e, UTF16) == pos(3, 1 + len(ODD))
    assert lines.offset(pos(3, 1 + len(ODD)), UTF16) == at_e
    assert lines.offset(pos(2, 0), UTF16) == text.index("c")


def test_line_start_and_end() -> None:
    text = "ab\rcd\r\nef"
    assert line_start(text, text.index("d")) == text.index("c")
    assert line_end(text, text.index("c")) == text.index("d") + 1
    assert line_start(text, text.index("f")) == text.index("e")
    assert line_end(text, text.index("e")) == len(text)


def test_columns_count_code_units_of_the_encoding() -> None:
    line = "x = \"é😀\u2028\" + y"
    lines = LineIndex(line)
    at_y = line.index("y")
    assert lines.position(at_y, UTF16).character == at_y + 1          # 😀: two units
    assert lines.position(at_y, UTF8).character == len(line[:at_y].encode())
    assert lines.position(at_y, UTF32).character == at_y
    for enc in (UTF8, UTF16, UTF32):
        assert lines.offset(lines.position(at_y, enc), enc) == at_y
        assert units(line, enc) == lines.position(len(line), enc).character
    # inside the surrogate pair of 😀: the character after it
    assert lines.offset(pos(0, line.index("😀") + 1), UTF16) == line.index("😀") + 1


@given(st.text(alphabet=st.sampled_from(list("ab é😀\n\r") + list(ODD)), max_size=60),
       st.data())
def test_offsets_and_positions_round_trip(text: str, data: st.DataObject) -> None:
    lines = LineIndex(text)
    offset = data.draw(st.integers(0, len(text)))
    if offset and text[offset - 1:offset + 1] == "\r\n":
        offset -= 1   # between CR and LF is no position of its own
    for enc in (UTF8, UTF16, UTF32):
        p = lines.position(offset, enc)
        assert lines.offset(p, enc) == offset
        assert p.line == count_lines(text[:offset]) - 1


def test_spans_are_placed_by_their_offsets() -> None:
    text = "a\rbb\rccc nowhere"
    at = text.index("nowhere")
    # the compiler's line and column are ignored when the offsets are there
    span = Span("f", 1, at + 1, 1, at + 8, at, at + 7)
    assert LineIndex(text).range(span, UTF16) == lsp.Range(start=pos(2, 4), end=pos(2, 11))
    # the compiler's offsets count from after a byte-order mark
    bom = LineIndex("\ufeff" + text)
    assert bom.range(span, UTF16) == lsp.Range(start=pos(2, 4), end=pos(2, 11))


def test_a_1mb_line_converts_fast() -> None:
    line = ("agent a { } é😀 " * 70_000)[:1_000_000]
    lines = LineIndex(line)
    start = time.perf_counter()
    for k in range(0, 1_000_000, 100):
        p = lines.position(k, UTF16)
        assert lines.offset(p, UTF16) == k
    assert time.perf_counter() - start < 2.0   # 10,000 round trips


def _document(text: str) -> LspLinesDocument:
    return LspLinesDocument("file:///t.rssm", text, version=1)


@pytest.mark.parametrize("sep", ["\n", "\r\n", "\r"])
def test_incremental_edits_land_on_lsp_lines(sep: str) -> None:
    text = sep.join(["// a \u2028 b \u2029 c \x85 d", "param p = 1", "end"])
    doc = _document(text)
    line = 1
    col = "param p = 1".index("1")
    doc.apply_change(lsp.TextDocumentContentChangePartial(
        range=lsp.Range(start=pos(line, col), end=pos(line, col + 1)), text="2 + x"))
    assert doc.source == text.replace("= 1", "= 2 + x")
    assert doc.lines[1] == "param p = 2 + x" + sep


def test_an_edit_past_the_end_of_a_line_stops_at_its_end() -> None:
    doc = _document("ab\r\ncd")
    doc.apply_change(lsp.TextDocumentContentChangePartial(
        range=lsp.Range(start=pos(0, 99), end=pos(0, 99)), text="!"))
    assert doc.source == "ab!\r\ncd"


@given(st.text(alphabet=st.sampled_from(list("ab\n\r ") + list(ODD)), max_size=40))
def test_the_same_lines_as_the_compiler(text: str) -> None:
    """One definition of lines (rssm_dsl.source): the editor's lines are the compiler's."""
    lines = LineIndex(text)
    assert [lines.line(n) for n in range(len(lines.starts))] == source.split_lines(text)
    assert list(lines.starts) == source.line_starts(text)
    assert count_lines(text) == len(source.line_starts(text))
