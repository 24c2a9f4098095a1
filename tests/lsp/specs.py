"""Specifications with the common mistakes, made from the paper's example."""

from __future__ import annotations

from tests.lsp.helpers import EXAMPLE

GOOD = EXAMPLE.read_text(encoding="utf-8")

_OTHERWISE = "          otherwise:\n            skip\n        }\n        update memory"
assert _OTHERWISE in GOOD
# E501: `update torque` covers two of the four data-availability combinations
MISSING_CASE = GOOD.replace(_OTHERWISE, "        }\n        update memory", 1)

_SWITCH = "      switch ccw -> cw when full_circle\n"
assert _SWITCH in GOOD
# E603: behaviour ccw can end but no switch leaves it
MISSING_SWITCH = GOOD.replace(_SWITCH, "", 1)

_CMD = "      output cmd: CartesianSetpoint to e.lwr nonblocking\n"
assert _CMD in GOOD
# E304: c receives `fb` from e.lwr, which declares no output for it
MISSING_BUFFER = GOOD.replace(_CMD, _CMD + "      input fb: float from e.lwr blocking\n", 1)
# E304: c sends to a buffer of e.lwr that does not exist
MISSING_NAMED_BUFFER = GOOD.replace(_CMD, _CMD + "      output gain: float to e.lwr.gain\n", 1)

# a syntax error inside the control subsystem's behaviour cw
_STMT = "cmd := circle_setpoint(radius, period, phase, -1.0)"
assert _STMT in GOOD
BROKEN_CW = MISSING_CASE.replace(_STMT, _STMT + " +* 2", 1)
