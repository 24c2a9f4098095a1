"""Outputs of `rssmc compile`: canonical text dump, JSON IR, DOT per layer, PNML.

Each emitter is a pure function from the IR to text; EMITTERS maps an --emit name to the
function producing {relative path: text}."""

from __future__ import annotations

from collections.abc import Callable

from rssm_dsl.emit.dot import emit_dot
from rssm_dsl.emit.dump import emit_dump
from rssm_dsl.emit.json_ir import emit_json
from rssm_dsl.emit.pnml import emit_pnml
from rssm_dsl.hpn.ir import HPN

Emitter = Callable[[HPN], dict[str, str]]

EMITTERS: dict[str, Emitter] = {
    "json": emit_json,
    "dump": emit_dump,
    "dot": emit_dot,
    "pnml": emit_pnml,
}
