"""The compiler pipeline: load and parse -> analyze -> build the HPN -> (backends)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic, DiagnosticBag
from rssm_dsl.gcpause import collector_paused
from rssm_dsl.semantics.analyze import AgentMemo, analyze
from rssm_dsl.semantics.loader import Loader, Program
from rssm_dsl.semantics.model import System
from rssm_dsl.source import Span

if TYPE_CHECKING:
    from rssm_dsl.hpn.ir import HPN


@dataclass(frozen=True)
class Compilation:
    path: Path
    program: Program
    system: System | None
    hpn: HPN | None
    diagnostics: tuple[Diagnostic, ...]

    @property
    def ok(self) -> bool:
        return not any(d.is_error for d in self.diagnostics)


def compile_file(path: Path, overrides: dict[Path, str] | None = None,
                 build: bool = True, memo: AgentMemo | None = None) -> Compilation:
    """Compile one root file. Never raises on bad input: problems are diagnostics. With
    `memo` (see semantics.analyze), agents analysed before are reused."""
    with collector_paused():
        return _compile(path, overrides, build, memo)


def _compile(path: Path, overrides: dict[Path, str] | None, build: bool,
             memo: AgentMemo | None) -> Compilation:
    bag = DiagnosticBag()
    at = Span(str(path), 1, 1, 1, 1)
    program = Loader(bag, overrides).load_root(path, at)
    system = None
    if not bag.has_errors:
        system = analyze(program, bag, memo)
    hpn = None
    if build and system is not None and not bag.has_errors:
        from rssm_dsl.hpn.build import build_hpn  # not needed by `rssmc check`

        hpn = build_hpn(system)
    return Compilation(path, program, system, hpn, tuple(bag.sorted()))
