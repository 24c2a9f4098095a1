"""Cross-check of the flattening: cpncheck explores the `.cpn` of the unflattened HPN.

cpncheck (PyPI) reads a CPN Tools file with its pages, substitution transitions, port/socket
assignments and fusion groups, expands the hierarchy itself and builds the occurrence graph.
Its state count, dead markings and place bounds must equal what our full exploration of the
flattened net finds. It is a pure-Python coloured-net simulator, far slower than our explorer:
keep it to nets of a few thousand states. It is an optional test dependency; when it is not
installed the result says so.

The HPN exported carries new(x) of the subsystems' inputs as fusion sets
(``datanet.tracked_hpn``): its flattening is the net the verifier explores, so the two state
spaces compare, and cpncheck checks the new(x) encoding of ``datanet`` as well.
"""

from __future__ import annotations

import importlib
import tempfile
import time
from pathlib import Path
from typing import Any

from rssm_core.records import dataclass
from rssm_dsl.emit.cpn import hpn_cpn
from rssm_dsl.hpn.ir import HPN
from rssm_dsl.verify.datanet import tracked_hpn

DEFAULT_MAX_STATES = 20_000


@dataclass(frozen=True, slots=True)
class CpnCheckResult:
    available: bool                 # cpncheck is installed
    ran: bool                       # it read the net and explored it
    message: str
    states: int = 0
    arcs: int = 0
    dead: int = 0                   # markings with nothing enabled
    deadlocks: int = 0              # dead markings without the system's end place marked
    unsafe: bool = False            # some reachable marking has two tokens on a place
    complete: bool = False          # explored every reachable marking
    places: int = 0                 # places after cpncheck expanded the hierarchy
    transitions: int = 0
    seconds: float = 0.0
    # with keep_markings: every reachable marking as the names of its marked places, named
    # like the flattened net's places (a fusion set by its id, any other place by its IR id)
    markings: frozenset[frozenset[str]] | None = None

    @property
    def deadlock_free(self) -> bool | None:
        if self.deadlocks:
            return False
        return True if self.complete else None


def _cpncheck() -> Any | None:
    try:
        return importlib.import_module("cpncheck")
    except ImportError:
        return None


def run_cpncheck(hpn: HPN, max_states: int = DEFAULT_MAX_STATES,
                 keep_markings: bool = False) -> CpnCheckResult:
    """Export the HPN as `.cpn`, have cpncheck expand the hierarchy and explore it, and count
    (and, with ``keep_markings``, return every reachable marking). The HPN is given new(x)
    as fusion sets, so that its flattening is the net the verifier explores
    (``datanet.tracked_hpn``)."""
    hpn = tracked_hpn(hpn)
    cc = _cpncheck()
    if cc is None:
        return CpnCheckResult(False, False, "cpncheck is not installed (pip install cpncheck)")
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="rssmc-cpn-") as tmp:
        path = Path(tmp) / "net.cpn"
        path.write_text(hpn_cpn(hpn), encoding="utf-8")
        try:
            net = cc.ColouredNet(cc.CPNNet(str(path)))
        except cc.UnsupportedNet as exc:
            return CpnCheckResult(True, False, f"cpncheck refused the net: {exc}",
                                  seconds=time.perf_counter() - start)
        space = cc.build_state_space(net, max_nodes=max_states)
    root = hpn.pages[hpn.root]
    end = [i for i, p in enumerate(net.places)
           if p["page"] == root.id and p["name"] == root.out_place]
    markings: list[tuple[tuple[Any, ...], ...]] = space.markings
    deadlocks = sum(1 for n in space.dead if not any(markings[n][i] for i in end))
    unsafe = any(len(tokens) > 1 for m in markings for tokens in m)
    named: frozenset[frozenset[str]] | None = None
    if keep_markings:
        names = [_flat_name(p) for p in net.places]
        named = frozenset(frozenset(names[i] for i, tokens in enumerate(m) if tokens)
                          for m in markings)
    return CpnCheckResult(
        True, True, "explored" if space.complete else f"stopped after {max_states:,} states",
        states=space.n_nodes, arcs=space.n_arcs, dead=len(space.dead), deadlocks=deadlocks,
        unsafe=unsafe, complete=bool(space.complete), places=len(net.places),
        transitions=len(net.transitions), seconds=time.perf_counter() - start, markings=named)


def _flat_name(place: dict[str, Any]) -> str:
    """The flattened net's name of a place cpncheck made: its fusion group's name for a fusion
    set, else its own name (a port place takes its socket's entry, named after the port)."""
    gid = str(place["gid"])
    return gid[len("fusion:"):] if gid.startswith("fusion:") else str(place["name"])
