"""What a structural check sees."""

from __future__ import annotations

from dataclasses import dataclass, field

from rssm_dsl.diagnostics import DiagnosticBag
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
