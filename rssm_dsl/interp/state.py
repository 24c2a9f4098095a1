"""Run-time state of subsystems and devices: their variables, the data-availability flags,
behaviour bookkeeping and counters.

Memory versions: during the transition function page P^f every partial function reads the
pre-state ``vars`` (inputs, memory s^i, outputs) and writes only its own target into
``stage``; the join transition of P^f commits ``stage`` into ``vars`` (memory s^{i+1} and the
new outputs) and clears every new(x). A receive writes the input buffer in ``vars`` and sets
new(x) for it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import field
from typing import Any

from rssm_core.iteration import NewFlags, end_conditions
from rssm_core.records import dataclass
from rssm_dsl.interp.clock import Ticker
from rssm_dsl.interp.device import Device as DeviceImpl
from rssm_dsl.interp.errors import EvalError
from rssm_dsl.semantics.model import Device, Subsystem

Predicate = Callable[[dict[str, Any]], Any]


@dataclass(eq=False)
class BehaviourState:
    name: str
    conditions: list[tuple[str, str, Predicate]]    # (name, "terminal" | "error", predicate)
    iterations: int = 0

    @property
    def has_error_condition(self) -> bool:
        return any(kind == "error" for _, kind, _ in self.conditions)


@dataclass(eq=False)
class SubsystemState:
    model: Subsystem
    vars: dict[str, Any]
    behaviours: dict[str, BehaviourState]
    ticker: Ticker | None
    inputs: tuple[str, ...]
    stage: dict[str, Any] = field(default_factory=dict)
    new: NewFlags = field(default_factory=lambda: NewFlags(0))
    i: int = 0                                   # the discrete time stamp of the paper
    completed: int = 0                           # iterations completed (t_4 or t_out fired)
    behaviour: str | None = None                 # current behaviour; None before/after
    started: bool = False
    ended: bool = False
    switches: int = 0
    conds: dict[str, bool] | None = None         # conditions at the end of this iteration
    stop_value: bool = False
    last_conds: dict[str, bool] = field(default_factory=dict)  # of the behaviour that ended
    failed: EvalError | None = None              # an operation failed in this iteration
    handled_errors: int = 0
    # called with a terminal or error condition that failed to evaluate (handled: the
    # error conditions hold); the runtime records it in the trace as it does an operation's
    condition_failed: Callable[[EvalError], None] | None = None
    condition_places: dict[str, str] = field(default_factory=dict)   # behaviour -> its place

    def __post_init__(self) -> None:
        self.new = NewFlags(len(self.inputs))

    @property
    def new_mask(self) -> int:
        """new(x) of the inputs as frozen for the transition function (bit k: input k)."""
        return self.new.mask

    @property
    def id(self) -> str:
        return self.model.id

    def stop(self) -> bool:
        """f^tau or f^eps of the current behaviour, evaluated once per iteration end."""
        if self.conds is None:
            self.evaluate_conditions()
        return self.stop_value

    def evaluate_conditions(self) -> None:
        assert self.behaviour is not None
        beh = self.behaviours[self.behaviour]

        def fail(e: Exception) -> None:
            if not isinstance(e, EvalError) or not beh.has_error_condition:
                raise e
            self.fail(e)
            if self.condition_failed is not None:
                self.condition_failed(e)

        self.conds = end_conditions(beh.conditions, self.vars, self.failed is not None, fail)
        self.stop_value = any(self.conds.values())

    def fail(self, error: EvalError) -> None:
        """An operation failed; the behaviour's error conditions will hold at its end."""
        if self.failed is None:
            self.failed = error
        self.handled_errors += 1

    def can_handle(self) -> bool:
        return (self.behaviour is not None
                and self.behaviours[self.behaviour].has_error_condition)


@dataclass(eq=False)
class DeviceState:
    model: Device
    vars: dict[str, Any]
    impl: DeviceImpl
    ticker: Ticker | None
    steps: int = 0
    last_step: int | None = None                 # ns of the previous step

    @property
    def id(self) -> str:
        return self.model.id
