"""The Python side of the specification, found without running it (rssm_dsl.bindings): each
extern's ``module:function`` and each used device type's ``module:Class`` exists where the
interpreter will look for it (E216), and a function takes the extern's arguments (E217). The
same lookups and the same arity rule as `rssmc simulate` (E801, E804 there), so that `rssmc
check` reports what a run would, before it. A module that is not found at all is only a
warning (W218): it may be installed where the system runs (a vendor's driver on the robot),
not where it is checked. Nor is a module too large or too deeply nested to read (W228).
A binding not of the form module:attribute is E208, reported by the declarations."""

from __future__ import annotations

from pathlib import Path

from rssm_dsl.bindings import (
    BindingError,
    ModuleMissing,
    ModuleUnreadable,
    arity_problem,
    binding_dirs,
    split_binding,
    static_lookup,
)
from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.semantics.checks.context import CheckContext
from rssm_dsl.source import Span


def check_bindings(ctx: CheckContext) -> None:
    root = Path(ctx.root_file).parent if ctx.root_file else None
    for ext in ctx.system.externs:
        if not _well_formed(ext.binding):
            continue
        try:
            found = static_lookup(ext.binding, binding_dirs(ext.span.file, root))
        except BindingError as e:
            _report(ctx.bag, e, f"extern {ext.name}", ext.span)
            continue
        if found is not None and found.signature is not None:
            why = arity_problem(found.signature, len(ext.params))
            if why is not None:
                ctx.bag.error("E217", f"\"{ext.binding}\" cannot take the {len(ext.params)} "
                              f"argument(s) of extern {ext.name}: {why}", ext.span,
                              "make the Python function's parameters match the extern")
    seen: set[tuple[str, str | None]] = set()
    for d in ctx.system.devices():
        if (d.binding is None or not _well_formed(d.binding)
                or (d.binding, _file(d.binding_span)) in seen):
            continue
        seen.add((d.binding, _file(d.binding_span)))
        at = d.binding_span or d.span
        try:
            found = static_lookup(d.binding, binding_dirs(_file(d.binding_span), root))
        except BindingError as e:
            _report(ctx.bag, e, f"device type {d.device_type}", at)
            continue
        if found is not None and found.kind == "function":
            ctx.bag.error("E216", f"\"{d.binding}\" of device type {d.device_type} is a "
                          "function, not a class", at, "bind the device type to a class")


def _report(bag: DiagnosticBag, e: BindingError, what: str, at: Span) -> None:
    if isinstance(e, ModuleUnreadable):
        bag.warn("W228", f"{what}: {e.message}", at, e.hint)
    elif isinstance(e, ModuleMissing):
        bag.warn("W218", f"{what}: {e.message}", at,
                 f"{e.hint}; or install it here (`rssmc simulate` needs it; a system that "
                 "runs elsewhere needs it there)")
    else:
        bag.error("E216", f"{what}: {e.message}", at, e.hint)


def _well_formed(binding: str) -> bool:
    try:
        split_binding(binding)
    except BindingError:
        return False
    return True


def _file(span: Span | None) -> str | None:
    return span.file if span is not None else None
