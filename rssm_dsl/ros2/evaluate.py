"""Values the generator needs at generation time, computed as the interpreter computes them:
the constants, every parameter's value (the default of its ROS parameter) and the initial
values of device buffers. A failure (division by zero in a constant...) is a diagnostic."""

from __future__ import annotations

from typing import Any

from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.interp.compile_expr import ExprCompiler
from rssm_dsl.interp.errors import EvalError
from rssm_dsl.interp.values import default_value
from rssm_dsl.semantics.model import Device, Subsystem, System, Variable
from rssm_dsl.semantics.typecheck import Symbol


class SpecValues:
    def __init__(self, system: System) -> None:
        self.system = system
        self.diagnostics: list[Diagnostic] = []
        self.consts: dict[str, Any] = {}
        self.const_symbols: dict[str, Symbol] = {}
        self.params: dict[tuple[str, str], Any] = {}       # (owner id, name) -> value
        self.buffers: dict[tuple[str, str], Any] = {}
        try:
            for c in system.consts:
                fn = ExprCompiler(self.const_symbols, {}, self.consts).expr(c.value, c.type)
                self.consts[c.name] = fn({})
                self.const_symbols[c.name] = Symbol("const", c.type, c.span)
        except EvalError as e:
            self.diagnostics.append(e.diagnostic())
            return
        for sub in system.subsystems():
            self._owner(sub)
        for dev in system.devices():
            self._owner(dev)

    def _owner(self, owner: Subsystem | Device) -> None:
        env: dict[str, Any] = {}
        symbols = dict(self.const_symbols)
        try:
            for p in owner.params:
                assert p.init is not None
                env[p.name] = ExprCompiler(symbols, {}, self.consts).expr(p.init, p.type)(env)
                symbols[p.name] = Symbol("param", p.type, p.span)
                self.params[owner.id, p.name] = env[p.name]
            for b in (*owner.inputs, *owner.outputs):
                value = (ExprCompiler(symbols, {}, self.consts).expr(b.init, b.type)(env)
                         if b.init is not None else default_value(b.type))
                self.buffers[owner.id, b.name] = value
        except EvalError as e:
            self.diagnostics.append(e.diagnostic())

    def param(self, owner: str, p: Variable) -> Any:
        return self.params.get((owner, p.name), default_value(p.type))

    def buffer(self, owner: str, name: str) -> Any:
        return self.buffers[owner, name]
