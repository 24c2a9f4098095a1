"""The behaviour pattern read back from the HPN (rssm_dsl/hpn/pattern.py), which the ROS 2
generator uses instead of the semantic model: the order of the steps of an iteration, and
every arrangement of the send and receive pages, equal to what the specification wrote."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.hpn.ir import PageKind
from rssm_dsl.hpn.pattern import Compute, Increment, Receive, Send, iteration
from rssm_dsl.semantics.model import Arrangement, ArrLeaf, ArrPar
from tests.conftest import example_specs
from tests.interp.conftest import compile_text


def shape(a: Arrangement | None) -> object:
    """An arrangement without spans; parallel items as a set (their order means nothing)."""
    if a is None:
        return None
    if isinstance(a, ArrLeaf):
        return a.buffer
    kind = "par" if isinstance(a, ArrPar) else "seq"
    items: list[object] = []
    for x in a.items:             # `(a ; b) ; c` is `a ; b ; c`, and so for `|`
        sx = shape(x)
        nested = isinstance(sx, tuple) and sx[0] == kind
        items += list(sx[1]) if nested else [sx]   # type: ignore[index, call-overload]
    return ("par", frozenset(items)) if kind == "par" else ("seq", tuple(items))


ARRANGEMENTS = [
    "a", "a ; b", "a | b", "a ; b ; c ; d", "a | b | c | d", "(a ; b) | c", "(a | b) ; c",
    "a ; (b | c)", "(a ; b) | (c ; d)", "(a | b) ; (c | d)", "((a ; b) | c) ; d",
    "a ; (b | (c ; d))", "(a | (b ; c)) ; d", "((a | b) ; c) | d",
]


SEND_NAMES = str.maketrans("abcd", "wxyz")


def _spec(receive: str, send: str) -> str:
    """c receives a, b, c, d from the effector arm and sends it w, x, y, z."""
    inputs = "\n".join(f"      input {x}: float from e.arm nonblocking" for x in "abcd")
    outputs = "\n".join(f"      output {x}: float to e.arm nonblocking" for x in "wxyz")
    e_out = "\n".join(f"      output {x}: float to c nonblocking" for x in "abcd")
    e_in = "\n".join(f"      input {x}: float from c nonblocking" for x in "wxyz")
    c_updates = "\n".join(f"        update {x} {{ {x} := 1.0 }}" for x in "wxyz")
    e_updates = "\n".join(f"        update {x} {{ {x} := 1.0 }}" for x in "abcd")
    return f"""
system t {{
  agent a1 {{
    control c {{
{inputs}
{outputs}
      behaviour b {{
{c_updates}
        terminal never when false
        send {send}
        receive {receive}
      }}
      initial b
    }}
    effector arm {{
{e_in}
{e_out}
      behaviour b {{
{e_updates}
        terminal never when false
        send a; b; c; d
        receive w; x; y; z
      }}
      initial b
    }}
  }}
}}
"""


@pytest.mark.parametrize("arr", ARRANGEMENTS)
def test_arrangements_are_read_back_from_the_net(tmp_path: Path, arr: str) -> None:
    used = sorted(set(arr) & set("abcd"))
    rest = [x for x in "abcd" if x not in used]
    full = f"({arr}) ; {' ; '.join(rest)}" if rest else arr
    comp = compile_text(tmp_path, _spec(receive=full, send=full.translate(SEND_NAMES)))
    assert comp.system is not None and comp.hpn is not None
    beh = comp.system.agents[0].subsystems[0].behaviours[0]
    page = next(p for p in comp.hpn.pages.values()
                if p.kind is PageKind.BEHAVIOUR and p.owner == "a1.c")
    steps = iteration(comp.hpn, page)
    send = next(s for s in steps if isinstance(s, Send))
    receive = next(s for s in steps if isinstance(s, Receive))
    assert shape(send.arrangement) == shape(beh.send)
    assert shape(receive.arrangement) == shape(beh.receive)


@pytest.mark.parametrize("spec", example_specs(), ids=lambda p: p.stem)
def test_every_behaviour_page_runs_compute_send_increment_receive(spec: Path) -> None:
    comp = compile_text(spec.parent, spec.read_text(), spec.name)
    assert comp.system is not None and comp.hpn is not None
    by_page = {}
    for sub in comp.system.subsystems():
        for beh in sub.behaviours:
            by_page[sub.id, beh.name] = beh
    pages = [p for p in comp.hpn.pages.values() if p.kind is PageKind.BEHAVIOUR]
    assert pages
    for page in pages:
        assert page.behaviour is not None
        beh = by_page[page.owner, page.behaviour]
        steps = iteration(comp.hpn, page)
        want: list[type] = [Compute]
        if beh.send is not None:
            want.append(Send)
        want.append(Increment)
        if beh.receive is not None:
            want.append(Receive)
        assert [type(s) for s in steps] == want, page.id
        for s in steps:
            if isinstance(s, Send):
                assert shape(s.arrangement) == shape(beh.send)
            if isinstance(s, Receive):
                assert shape(s.arrangement) == shape(beh.receive)
