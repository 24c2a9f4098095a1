"""What a structural check sees."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import field, replace

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic, DiagnosticBag
from rssm_dsl.semantics.model import System
from rssm_dsl.syntax import ast


@dataclass(frozen=True)
class CheckContext:
    bag: DiagnosticBag
    system: System
    decls: dict[str, ast.SubsystemDecl]     # subsystem id -> its declaration
    written: dict[str, set[str]]            # subsystem id -> outputs/memory written
    read: dict[str, set[str]]               # subsystem id -> names its expressions read
    # subsystem id -> behaviours with a switch that has errors: their switches are not
    # checked again, nor the reachability of the subsystem's behaviours
    unchecked: dict[str, set[str]] = field(default_factory=dict)
    # subsystem id -> its variables and parameters that properties read (they count as used)
    property_reads: dict[str, set[str]] = field(default_factory=dict)
    # the root specification as spans name it (its folder is where bindings are looked up)
    root_file: str | None = None
    # what a check found for parts of the model it saw in an earlier analysis (see reuse)
    cache: CheckCache | None = None

    def reuse(self, key: tuple[object, ...], check: Callable[[CheckContext], None]) -> None:
        """Run `check`, or report what it reported when it last ran on the same `key`: the
        objects of the model it reads (compared by identity: an unchanged agent's are the
        same objects from one analysis to the next, rssm_dsl.semantics.analyze.AgentMemo)
        and the values that identify them (compared by equality)."""
        if self.cache is None:
            check(self)
            return
        found = self.cache.get(key)
        if found is None:
            bag = DiagnosticBag()
            check(replace(self, bag=bag))
            found = tuple(bag.items)
        self.cache.keep(key, found)
        for d in found:
            self.bag.add(d)


class CheckCache:
    """The diagnostics of checks by key: of the last analysis (`last`), and of this one so
    far (`now`: what the next analysis may reuse)."""

    def __init__(self, last: CheckCache | None = None) -> None:
        self.last: dict[tuple[object, ...], tuple[tuple[object, ...], tuple[Diagnostic, ...]]] \
            = last.now if last is not None else {}
        self.now: dict[tuple[object, ...], tuple[tuple[object, ...], tuple[Diagnostic, ...]]] \
            = {}

    @staticmethod
    def _id(key: tuple[object, ...]) -> tuple[object, ...]:
        return tuple(x if isinstance(x, str | int) else id(x) for x in key)

    def get(self, key: tuple[object, ...]) -> tuple[Diagnostic, ...] | None:
        got = self.last.get(self._id(key))
        if got is None or len(got[0]) != len(key) or not all(
                a is b or (isinstance(a, str | int) and a == b)
                for a, b in zip(got[0], key, strict=True)):
            return None
        return got[1]

    def keep(self, key: tuple[object, ...], found: tuple[Diagnostic, ...]) -> None:
        self.now[self._id(key)] = (key, found)
