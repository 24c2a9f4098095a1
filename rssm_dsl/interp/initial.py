"""The values a system starts with, computed once for every backend: the constants, every
parameter's value, the initial values of memory variables and buffers (declared values, or
the default of the type). The interpreter starts its subsystems and devices from them; the
ROS 2 generator writes them as the defaults of the nodes' parameters and the initial values
of device buffers. A failure (a division by zero in a constant...) is a diagnostic, and the
values of that owner are left out."""

from __future__ import annotations

from typing import Any

from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.interp.compile_expr import ExprCompiler
from rssm_dsl.interp.errors import EvalError
from rssm_dsl.interp.values import default_value
from rssm_dsl.semantics.model import Device, Subsystem, System, Variable
from rssm_dsl.semantics.typecheck import Symbol, enum_symbols


class InitialValues:
    """``consts`` by name; ``params``, ``memory`` and ``buffers`` by (owner id, name);
    ``diagnostics`` for what could not be computed."""

    def __init__(self, system: System) -> None:
        self.system = system
        self.diagnostics: list[Diagnostic] = []
        self.consts: dict[str, Any] = {}
        # the constants' types, and the enum types (whose members expressions name)
        self.const_symbols: dict[str, Symbol] = enum_symbols(system.types, system.span)
        self.params: dict[tuple[str, str], Any] = {}
        self.memory: dict[tuple[str, str], Any] = {}
        self.buffers: dict[tuple[str, str], Any] = {}
        self._envs: dict[str, dict[str, Any]] = {}
        try:
            for c in system.consts:
                fn = ExprCompiler(self.const_symbols, {}, self.consts).expr(c.value, c.type,
                                                                            c.name)
                self.consts[c.name] = fn({})
                self.const_symbols[c.name] = Symbol("const", c.type, c.span)
        except EvalError as e:
            self.diagnostics.append(e.diagnostic())
            return
        for sub in system.subsystems():
            self._owner(sub, sub.memory)
        for dev in system.devices():
            self._owner(dev, ())

    def _owner(self, owner: Subsystem | Device, memory: tuple[Variable, ...]) -> None:
        """Parameters in order (each may use the ones before), then memory and buffers."""
        env: dict[str, Any] = {}
        symbols = dict(self.const_symbols)
        try:
            for p in owner.params:
                assert p.init is not None
                env[p.name] = ExprCompiler(symbols, {}, self.consts).expr(p.init, p.type,
                                                                          p.name)(env)
                symbols[p.name] = Symbol("param", p.type, p.span)
                self.params[owner.id, p.name] = env[p.name]
            for table, variables in ((self.memory, memory),
                                     (self.buffers, (*owner.inputs, *owner.outputs))):
                for v in variables:
                    env[v.name] = table[owner.id, v.name] = (
                        ExprCompiler(symbols, {}, self.consts).expr(v.init, v.type,
                                                                    v.name)(env)
                        if v.init is not None else default_value(v.type))
        except EvalError as e:
            self.diagnostics.append(e.diagnostic())
        self._envs[owner.id] = env

    def env(self, owner: Subsystem | Device) -> dict[str, Any]:
        """The variables of ``owner`` at the start: parameters, memory, buffers (a fresh dict;
        empty when the constants could not be computed)."""
        return dict(self._envs.get(owner.id, {}))

    def param(self, owner: str, p: Variable) -> Any:
        return self.params.get((owner, p.name), default_value(p.type))

    def buffer(self, owner: str, name: str) -> Any:
        return self.buffers[owner, name]
