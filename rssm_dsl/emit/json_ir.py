"""The JSON form of the HPN IR, described by schema/hpn-ir.schema.json."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from rssm_dsl import __version__
from rssm_dsl.emit.order import pages_in_order
from rssm_dsl.filenames import file_name
from rssm_dsl.hpn.ir import HPN, Condition, Operation
from rssm_dsl.source import Span

SCHEMA_PATH = Path(__file__).parent / "schema" / "hpn-ir.schema.json"
FORMAT = "rssm-hpn-ir"
FORMAT_VERSION = 1


def _span(s: Span) -> dict[str, Any]:
    return {"file": s.file, "line": s.line, "column": s.column, "end_line": s.end_line,
            "end_column": s.end_column}


def _op(o: Operation | None) -> dict[str, Any] | None:
    if o is None:
        return None
    return {"kind": o.kind.value, "subsystem": o.subsystem, "text": o.text,
            "behaviour": o.behaviour, "target": o.target, "case": o.case,
            "channel": o.channel, "void": o.void}


def _cond(c: Condition | None) -> dict[str, Any] | None:
    if c is None:
        return None
    return {"kind": c.kind.value, "subsystem": c.subsystem, "text": c.text,
            "behaviour": c.behaviour, "new": list(c.new) if c.new is not None else None,
            "switch": c.switch, "constant": c.constant}


def to_json(hpn: HPN) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "generator": f"rssmc {__version__}",
        "system": hpn.system,
        "root": hpn.root,
        "devices": list(hpn.devices),
        "pages": [
            {"id": p.id, "kind": p.kind.value, "layer": p.layer, "sublayer": p.sublayer,
             "parent": p.parent, "in": p.in_place, "out": p.out_place, "label": p.label,
             "owner": p.owner, "behaviour": p.behaviour, "span": _span(p.span)}
            for p in pages_in_order(hpn)
        ],
        "places": [
            {"id": p.id, "page": p.page, "label": p.label, "initial": p.initial,
             "fusion": p.fusion, "operation": _op(p.operation), "span": _span(p.span)}
            for p in hpn.places.values()
        ],
        "transitions": [
            {"id": t.id, "page": t.page, "label": t.label, "role": t.role.value,
             "condition": _cond(t.condition), "span": _span(t.span)}
            for t in hpn.transitions.values()
        ],
        "arcs": [{"page": a.page, "source": a.source, "target": a.target} for a in hpn.arcs],
        "fusions": [
            {"id": f.id, "label": f.label, "channel": f.channel, "places": list(f.places),
             "initial": f.initial, "span": _span(f.span)}
            for f in hpn.fusions.values()
        ],
    }


def emit_json(hpn: HPN) -> dict[str, str]:
    return {file_name(hpn.system, ".hpn.json"): json.dumps(to_json(hpn), indent=1) + "\n"}
