"""What one iteration of a behaviour decides, defined once for the interpreter and the
generated ROS 2 nodes (paper IV; docs/language.md, "Behaviours"):

* ``new(x)`` of each input buffer (:class:`NewFlags`): set when a receive takes fresh data
  into ``x``; frozen into a bit mask when the transition function starts (the mask selects
  each partial function's data-availability case: bit k is ``new`` of input k); cleared for
  every input once the transition function has used the data (its join commits the memory
  and the outputs);
* the terminal and error conditions at the end of the iteration
  (:func:`end_conditions`): each is evaluated on the variables after the receive; an
  operation that failed during the iteration, or a condition that fails to evaluate, makes
  every error condition of the behaviour hold (and a failing condition itself is false); the
  behaviour ends when any condition holds.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

Predicate = Callable[[Any], Any]
Condition = tuple[str, str, Predicate]          # (name, "terminal" | "error", predicate)


class NewFlags:
    """``new(x)`` of a subsystem's inputs (input k is bit k of :attr:`pending` and
    :attr:`mask`)."""

    __slots__ = ("inputs", "mask", "pending")

    def __init__(self, inputs: int) -> None:
        self.inputs = inputs
        self.pending = 0          # new(x) as the receives have set it since the last use
        self.mask = 0             # ... as frozen for the transition function

    def received(self, k: int) -> None:
        """A receive took fresh data into input ``k``."""
        self.pending |= 1 << k

    def freeze(self) -> int:
        """The transition function starts: the mask its data cases are chosen by."""
        mask = self.mask = self.pending
        return mask

    def used(self) -> None:
        """The transition function has used the data: every new(x) is false again (the
        mask keeps what that transition function saw until the next :meth:`freeze`)."""
        self.pending = 0

    def values(self) -> list[bool]:
        """new(x) as the frozen mask gives it, input by input."""
        return [bool(self.mask >> k & 1) for k in range(self.inputs)]


def end_conditions(conditions: Sequence[Condition], state: Any, failed: bool,
                   fail: Callable[[Exception], None]) -> dict[str, bool]:
    """The terminal and error conditions of a behaviour at the end of an iteration.

    ``failed``: an operation of this iteration failed. ``fail`` is told of a condition that
    fails to evaluate; it raises when the behaviour has no error condition (the failure then
    stops the subsystem) and returns when it has one."""
    values: dict[str, bool] = {}
    for name, _, predicate in conditions:
        try:
            values[name] = bool(predicate(state))
        except Exception as e:
            fail(e)
            failed = True
            values[name] = False
    if failed:
        for name, kind, _ in conditions:
            if kind == "error":
                values[name] = True
    return values
