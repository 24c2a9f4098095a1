"""The JSON form of the HPN IR, described by schema/hpn-ir.schema.json.

`to_json` is the IR as JSON data; `emit_json` writes the text ``json.dumps(to_json(hpn),
indent=1)`` would (the same characters) without making that data: the standard encoder has
no C form with an indentation, and on a net of a few hundred thousand elements it took most
of `rssmc compile`'s time, and ten times the text's size in memory (a list of millions of
small strings), with the dicts of every row alive at once. Here each row is written from
the element as it is read, and the rows are joined a few thousand at a time: `rssmc
compile` writes the pieces as they come (stream_json), never the whole text (150 MB for
5,000 agents)."""

from __future__ import annotations

import itertools
import json
from collections.abc import Callable, Iterable, Iterator
from json.encoder import encode_basestring_ascii
from pathlib import Path
from typing import Any, cast

from rssm_dsl import __version__
from rssm_dsl.emit.order import pages_in_order
from rssm_dsl.filenames import file_name
from rssm_dsl.hpn.ir import HPN, Condition, FusionSet, Operation, Page, Place, Transition
from rssm_dsl.source import Span

SCHEMA_PATH = Path(__file__).parent / "schema" / "hpn-ir.schema.json"
FORMAT = "rssm-hpn-ir"
FORMAT_VERSION = 1

# the keys of each table's rows, in their order
_PAGE = ("id", "kind", "layer", "sublayer", "parent", "in", "out", "label", "owner",
         "behaviour", "span")
_PLACE = ("id", "page", "label", "initial", "fusion", "operation", "span")
_TRANSITION = ("id", "page", "label", "role", "condition", "span")
_ARC = ("page", "source", "target")
_FUSION = ("id", "label", "channel", "places", "initial", "span")
_OPERATION = ("kind", "subsystem", "text", "behaviour", "target", "case", "channel", "void")
_CONDITION = ("kind", "subsystem", "text", "behaviour", "new", "switch", "constant")


def _span(s: Span) -> dict[str, Any]:
    return {"file": s.file, "line": s.line, "column": s.column, "end_line": s.end_line,
            "end_column": s.end_column}


def _op(o: Operation | None) -> dict[str, Any] | None:
    if o is None:
        return None
    return dict(zip(_OPERATION, (o.kind.value, o.subsystem, o.text, o.behaviour, o.target,
                                 o.case, o.channel, o.void), strict=True))


def _cond(c: Condition | None) -> dict[str, Any] | None:
    if c is None:
        return None
    return dict(zip(_CONDITION, (c.kind.value, c.subsystem, c.text, c.behaviour,
                                 list(c.new) if c.new is not None else None, c.switch,
                                 c.constant), strict=True))


def _page(p: Page, span: object) -> tuple[object, ...]:
    return (p.id, p.kind.value, p.layer, p.sublayer, p.parent, p.in_place, p.out_place,
            p.label, p.owner, p.behaviour, span)


def _place(p: Place, span: object) -> tuple[object, ...]:
    return (p.id, p.page, p.label, p.initial, p.fusion, _op(p.operation), span)


def _transition(t: Transition, span: object) -> tuple[object, ...]:
    return (t.id, t.page, t.label, t.role.value, _cond(t.condition), span)


def _fusion(f: FusionSet, span: object) -> tuple[object, ...]:
    return (f.id, f.label, f.channel, list(f.places), f.initial, span)


def _head(hpn: HPN) -> dict[str, Any]:
    """The top object's values before the tables."""
    return {"format": FORMAT, "version": FORMAT_VERSION, "generator": f"rssmc {__version__}",
            "system": hpn.system, "root": hpn.root, "devices": list(hpn.devices)}


def to_json(hpn: HPN) -> dict[str, Any]:
    return {
        **_head(hpn),
        "pages": [dict(zip(_PAGE, _page(p, _span(p.span)), strict=True))
                  for p in pages_in_order(hpn)],
        "places": [dict(zip(_PLACE, _place(p, _span(p.span)), strict=True))
                   for p in hpn.places.values()],
        "transitions": [dict(zip(_TRANSITION, _transition(t, _span(t.span)), strict=True))
                        for t in hpn.transitions.values()],
        "arcs": [{"page": a.page, "source": a.source, "target": a.target} for a in hpn.arcs],
        "fusions": [dict(zip(_FUSION, _fusion(f, _span(f.span)), strict=True))
                    for f in hpn.fusions.values()],
    }


def _float(x: float) -> str:
    if x != x:
        return "NaN"
    if x in (float("inf"), float("-inf")):
        return "Infinity" if x > 0 else "-Infinity"
    return float.__repr__(x)


def _key(k: object) -> str:
    if isinstance(k, str):
        return encode_basestring_ascii(k)
    if k is True or k is False or k is None or isinstance(k, int | float):
        return encode_basestring_ascii(json.dumps(k))
    raise TypeError(f"keys must be str, int, float, bool or None, not {type(k).__name__}")


Encode = Callable[[object, str], str]


def _encoder() -> Encode:
    """``encode(o, pad)``: ``o`` as ``json.dumps(o, indent=1)`` writes it (the same text)
    on a line indented by ``pad``: each container's text is returned whole, and the keys of
    the dicts of one shape (string keys) are written once."""
    prefixes: dict[tuple[tuple[object, ...], str], list[str]] = {}

    def encode(o: object, pad: str) -> str:
        t = type(o)
        if t is dict:
            d = cast(dict[object, object], o)
            if not d:
                return "{}"
            inner = pad + " "
            shape = (tuple(d), inner)
            keys = prefixes.get(shape)
            if keys is None:
                keys = [f"{inner}{_key(k)}: " for k in shape[0]]
                if all(type(k) is str for k in shape[0]):  # (1,) == (True,): not kept
                    prefixes[shape] = keys
            return ("{\n" + ",\n".join([
                k + (encode_basestring_ascii(v) if type(v) is str else encode(v, inner))
                for k, v in zip(keys, d.values(), strict=True)]) + "\n" + pad + "}")
        if t is str:
            return encode_basestring_ascii(cast(str, o))
        if t is list or t is tuple:
            items = cast(list[object], o)
            if not items:
                return "[]"
            inner = pad + " "
            return ("[\n" + ",\n".join([
                inner + (encode_basestring_ascii(v) if type(v) is str else encode(v, inner))
                for v in items]) + "\n" + pad + "]")
        if o is None:
            return "null"
        if o is True:
            return "true"
        if o is False:
            return "false"
        if t is int:
            return int.__repr__(cast(int, o))
        if t is float:
            return _float(cast(float, o))
        if isinstance(o, str | int | float | dict | list | tuple):   # subclasses: as json does
            return json.dumps(o, indent=1).replace("\n", "\n" + pad)
        raise TypeError(f"Object of type {type(o).__name__} is not JSON serializable")

    return encode


def dumps(o: object) -> str:
    """``json.dumps(o, indent=1)``: the same text, faster and in less memory (_encoder)."""
    return _encoder()(o, "")


def _row_format(names: tuple[str, ...], pad: str) -> str:
    """The %-format of a dict with these keys, its values given as their JSON text,
    written by ``json.dumps(..., indent=1)`` on a line indented by ``pad``."""
    inner = pad + " "
    return ("{\n" + ",\n".join(f"{inner}{encode_basestring_ascii(n)}: %s" for n in names)
            .replace("%", "%%").replace("%%s", "%s") + "\n" + pad + "}")


_CHUNK = 4096   # rows joined into one piece of a streamed table (a few hundred kB)


def _table(fmt: str, rows: Iterable[tuple[str, ...]]) -> Iterator[str]:
    """A list of rows (``fmt``, their values' texts) as the value of a key of the top
    object (an IR table), in pieces of a few thousand rows."""
    fmt = "  " + fmt
    rows = iter(rows)
    first = True
    while chunk := [fmt % row for row in itertools.islice(rows, _CHUNK)]:
        yield ("[\n" if first else ",\n") + ",\n".join(chunk)
        first = False
    yield "[]" if first else "\n ]"


def json_text(hpn: HPN) -> str:
    """``json.dumps(to_json(hpn), indent=1)`` (see the module's docstring)."""
    return "".join(json_pieces(hpn))


def json_pieces(hpn: HPN) -> Iterator[str]:
    """``json.dumps(to_json(hpn), indent=1)`` in pieces, table by table, each table in
    pieces of a few thousand rows (see the module's docstring).
    A value is written by the C function for strings when it is one (nearly all), by the
    encoder otherwise (written out in each row: a call per value was most of the time)."""
    encode = _encoder()
    E = encode_basestring_ascii
    spans: dict[int, str] = {}   # by id: the elements of one construct share its span
    op_format, cond_format = _row_format(_OPERATION, "   "), _row_format(_CONDITION, "   ")
    P, Q = "   ", "    "         # the indents of a row's values, and of its dicts' values

    span_format = _row_format(("file", "line", "column", "end_line", "end_column"), P)

    def span(s: Span) -> str:
        got = spans.get(id(s))
        if got is None:
            f, a, b, c, d = s.file, s.line, s.column, s.end_line, s.end_column
            if type(f) is str and type(a) is int and type(b) is int and type(c) is int \
                    and type(d) is int:     # (the text of an int is its str)
                got = span_format % (E(f), a, b, c, d)
            else:
                got = encode(_span(s), P)
            spans[id(s)] = got
        return got

    def op(o: Operation | None) -> str:
        if o is None:
            return "null"
        return op_format % (
            encode(o.kind.value, Q), E(o.subsystem) if type(o.subsystem) is str else
            encode(o.subsystem, Q), E(o.text) if type(o.text) is str else encode(o.text, Q),
            encode(o.behaviour, Q), encode(o.target, Q), encode(o.case, Q),
            encode(o.channel, Q), encode(o.void, Q))

    def cond(c: Condition | None) -> str:
        if c is None:
            return "null"
        return cond_format % (
            encode(c.kind.value, Q), encode(c.subsystem, Q), encode(c.text, Q),
            encode(c.behaviour, Q), encode(list(c.new) if c.new is not None else None, Q),
            encode(c.switch, Q), encode(c.constant, Q))

    def tables() -> Iterator[tuple[str, Iterator[str]]]:      # one at a time
        # (the commonest values written out: None, False, strings, an enum's string value
        # read from the member without the `value` property; the encoder for the others)
        yield "pages", _table(_row_format(_PAGE, "  "), (
            (E(p.id) if type(p.id) is str else encode(p.id, P),
             E(k) if type(k := p.kind._value_) is str else encode(k, P),
             encode(p.layer, P), encode(p.sublayer, P),
             E(p.parent) if type(p.parent) is str else encode(p.parent, P),
             E(p.in_place) if type(p.in_place) is str else encode(p.in_place, P),
             E(p.out_place) if type(p.out_place) is str else encode(p.out_place, P),
             E(p.label) if type(p.label) is str else encode(p.label, P),
             E(p.owner) if type(p.owner) is str else encode(p.owner, P),
             E(p.behaviour) if type(p.behaviour) is str else encode(p.behaviour, P),
             span(p.span))
            for p in pages_in_order(hpn)))
        yield "places", _table(_row_format(_PLACE, "  "), (
            (E(p.id) if type(p.id) is str else encode(p.id, P),
             E(p.page) if type(p.page) is str else encode(p.page, P),
             E(p.label) if type(p.label) is str else encode(p.label, P),
             "false" if p.initial is False else encode(p.initial, P),
             "null" if p.fusion is None else encode(p.fusion, P),
             "null" if p.operation is None else op(p.operation),
             spans.get(id(p.span)) or span(p.span))
            for p in hpn.places.values()))
        yield "transitions", _table(_row_format(_TRANSITION, "  "), (
            (E(t.id) if type(t.id) is str else encode(t.id, P),
             E(t.page) if type(t.page) is str else encode(t.page, P),
             E(t.label) if type(t.label) is str else encode(t.label, P),
             E(r) if type(r := t.role._value_) is str else encode(r, P),
             cond(t.condition), spans.get(id(t.span)) or span(t.span))
            for t in hpn.transitions.values()))
        yield "arcs", _table(_row_format(_ARC, "  "), (
            (E(a.page) if type(a.page) is str else encode(a.page, P),
             E(a.source) if type(a.source) is str else encode(a.source, P),
             E(a.target) if type(a.target) is str else encode(a.target, P))
            for a in hpn.arcs))
        yield "fusions", _table(_row_format(_FUSION, "  "), (
            (encode(f.id, P), encode(f.label, P), encode(f.channel, P),
             encode(list(f.places), P), encode(f.initial, P), span(f.span))
            for f in hpn.fusions.values()))

    yield "{\n" + ",\n".join(f" {E(k)}: {encode(v, ' ')}" for k, v in _head(hpn).items())
    for key, table in tables():
        yield f",\n {E(key)}: "
        yield from table
    yield "\n}"


def emit_json(hpn: HPN) -> dict[str, str]:
    return {file_name(hpn.system, ".hpn.json"): json_text(hpn) + "\n"}


def stream_json(hpn: HPN) -> Iterator[tuple[str, Iterable[str]]]:
    """:func:`emit_json`'s file, its text in pieces (never held whole)."""
    yield file_name(hpn.system, ".hpn.json"), itertools.chain(json_pieces(hpn), ("\n",))
