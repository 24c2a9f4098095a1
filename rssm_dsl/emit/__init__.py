"""Outputs of `rssmc compile`: canonical text dump, JSON IR, DOT per layer, PNML (flat and
paged), CPN Tools `.cpn` of the unflattened HPN.

Each emitter is a pure function from the IR to text; EMITTERS maps an --emit name to the
function producing {relative path: text}. `rssmc compile` writes the same texts in pieces as
they are made, on two processes for a large net (rssm_dsl.emit.outputs.STREAMS)."""

from __future__ import annotations

from collections.abc import Callable

from rssm_dsl.emit.cpn import emit_cpn
from rssm_dsl.emit.dot import emit_dot
from rssm_dsl.emit.dump import emit_dump
from rssm_dsl.emit.json_ir import emit_json
from rssm_dsl.emit.pnml import emit_paged_pnml, emit_pnml
from rssm_dsl.hpn.ir import HPN

Emitter = Callable[[HPN], dict[str, str]]

EMITTERS: dict[str, Emitter] = {
    "json": emit_json,
    "dump": emit_dump,
    "dot": emit_dot,
    "pnml": emit_pnml,
    "pnml-paged": emit_paged_pnml,
    "cpn": emit_cpn,
}
