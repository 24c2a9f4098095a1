"""The one table of expected behaviour: what RSSM's communication modes,
arrangements, behaviour switching, terminal and error conditions and value operations mean,
written down once, from the RSSM HPN paper (sections III and IV), docs/language.md and
docs/semantics.md ("One iteration", "Communication modes").

Three runners check the same rows: the interpreter (test_interp.py, deterministic simulated
clock), the verifier's state space of the flat net (test_verify.py, as reachability questions
over markings) and the generated ROS 2 nodes over real DDS (test_ros2.py, marked ros2 and
slow). The value rows run on the interpreter and on the generated node code without ROS
(test_values.py), and so do the switching and ending rows (test_nodecode.py: the quick check
of the generated code; test_ros2.py runs them over DDS too). The rows say *what* happens;
each runner says how it observes it, and what it cannot observe (the verifier has no values
and no time; ROS 2 has real time, so its situations come from rate ratios).

Words used in the rows:

- a *sample* is one value a producer sends (one per producer iteration); the producers of
  these tests count, so sample k carries the value k;
- the *situation* of a receive is what the consumer's receive finds in the channel when it
  decides: nothing fresh (a blocking receive then waits: the situation is "no data" even
  though it ends up taking the next sample), exactly one fresh sample, or a fresh sample that
  replaced older ones nobody read;
- a sample is *lost* when a newer one overwrote it before any consumer took it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum


class Mode(str, Enum):
    BLOCKING = "blocking"
    NONBLOCKING = "nonblocking"

    @property
    def letter(self) -> str:
        return "b" if self is Mode.BLOCKING else "n"


class Situation(str, Enum):
    WAITING = "data waiting"              # exactly one fresh sample waits in the channel
    NO_DATA = "no data"                   # nothing fresh in the channel
    OVERWRITTEN = "overwritten before read"   # fresh data, and older samples were replaced


class Reads(str, Enum):
    """Which value the consumer's input buffer holds after the receive."""

    WAITING = "the sample waiting"        # the one fresh sample (the first and the newest)
    NEWEST = "the newest"                 # the last one sent; the ones before it are lost
    NEXT = "the next one sent"            # waits, then takes the first sample sent after
    PREVIOUS = "its previous value"       # takes nothing: the buffer keeps what it had


# ---------------------------------------------------------------------------- modes


@dataclass(frozen=True)
class ModeRow:
    producer: Mode
    consumer: Mode
    situation: Situation
    arises: bool              # False: these modes keep the situation from ever happening
    producer_waits: bool      # the producer's send completes only once the consumer took it
    consumer_waits: bool      # the consumer's receive waits for the producer's next sample
    reads: Reads | None       # None when the situation does not arise
    new: bool | None          # new(x) as the consumer's next transition function sees it
    lost: bool                # some sample was overwritten and never read
    why: str

    @property
    def pair(self) -> str:
        return self.producer.letter + self.consumer.letter

    @property
    def id(self) -> str:
        return f"{self.pair}-{self.situation.name.lower()}"


B, N = Mode.BLOCKING, Mode.NONBLOCKING
WAIT, NONE, OVER = Situation.WAITING, Situation.NO_DATA, Situation.OVERWRITTEN

_PB = "producer blocking: waits until the consumer has taken the data"
_PN = "producer non-blocking: continues at once, overwriting data never read"
_CB = "consumer blocking: waits for fresh data"
_CN = "consumer non-blocking: takes fresh data if any, otherwise keeps what it had"
_NEW = "new(x): true in the iteration after a receive that took fresh data"

MODE_ROWS: tuple[ModeRow, ...] = (
    # producer blocking, consumer blocking (fully synchronous)
    ModeRow(B, B, WAIT, True, True, False, Reads.WAITING, True, False, f"{_PB}; {_CB}; {_NEW}"),
    ModeRow(B, B, NONE, True, True, True, Reads.NEXT, True, False, f"{_CB}; {_NEW}"),
    ModeRow(B, B, OVER, False, True, False, None, None, False,
            f"{_PB}: it cannot send again before the consumer took the sample"),
    # producer blocking, consumer non-blocking
    ModeRow(B, N, WAIT, True, True, False, Reads.WAITING, True, False, f"{_PB}; {_CN}; {_NEW}"),
    ModeRow(B, N, NONE, True, True, False, Reads.PREVIOUS, False, False, f"{_CN}; {_NEW}"),
    ModeRow(B, N, OVER, False, True, False, None, None, False,
            f"{_PB}: it cannot send again before the consumer took the sample"),
    # producer non-blocking, consumer blocking
    ModeRow(N, B, WAIT, True, False, False, Reads.WAITING, True, False, f"{_PN}; {_CB}; {_NEW}"),
    ModeRow(N, B, NONE, True, False, True, Reads.NEXT, True, False, f"{_CB}; {_NEW}"),
    ModeRow(N, B, OVER, True, False, False, Reads.NEWEST, True, True, f"{_PN}; {_CB}"),
    # producer non-blocking, consumer non-blocking (fully asynchronous)
    ModeRow(N, N, WAIT, True, False, False, Reads.WAITING, True, False, f"{_PN}; {_CN}; {_NEW}"),
    ModeRow(N, N, NONE, True, False, False, Reads.PREVIOUS, False, False, f"{_CN}; {_NEW}"),
    ModeRow(N, N, OVER, True, False, False, Reads.NEWEST, True, True, f"{_PN}; {_CN}"),
)

PAIRS: tuple[tuple[Mode, Mode], ...] = ((B, B), (B, N), (N, B), (N, N))


def mode_row(producer: Mode, consumer: Mode, situation: Situation) -> ModeRow:
    return next(r for r in MODE_ROWS
                if (r.producer, r.consumer, r.situation) == (producer, consumer, situation))


# ---------------------------------------------------------------------------- the pattern


@dataclass(frozen=True)
class PatternRow:
    """The fixed order of one iteration: P^f (transition function) -> P_snd (send) ->
    i := i + 1 -> P_rcv (receive) -> terminal and error conditions (docs/semantics.md#one-iteration)."""

    id: str
    statement: str


PATTERN_ROWS: tuple[PatternRow, ...] = (
    PatternRow("compute-then-send",
               "the sample sent in an iteration is the output that iteration's transition "
               "function computed (the first sample is 1, never the buffer's initial 0)"),
    PatternRow("receive-then-use",
               "a value received in iteration i is used by the transition function of "
               "iteration i + 1, which sees new(x) true; the next one sees new(x) false "
               "unless another receive took fresh data (new() is cleared once used)"),
    PatternRow("receive-then-conditions",
               "the terminal conditions of an iteration are evaluated after its receive: they "
               "see the value received in the same iteration"),
)


# ---------------------------------------------------------------------------- arrangements


@dataclass(frozen=True)
class ArrangementRow:
    """Two buffers a and b on one side of a subsystem; a's peer is slow (a blocking receive of
    a waits for data; a blocking send of a waits for its consumer), b's peer is fast (b's
    data is always there; b's consumer takes at once)."""

    side: str                 # "receive" | "send"
    arrangement: str          # as written in the spec
    order: tuple[str, ...] | None   # the order in which the operations complete in every
    #                                 iteration, or None when it is not fixed
    b_while_a_waits: bool     # b's operation completes while a's waits
    statement: str

    @property
    def id(self) -> str:
        kind = {";": "seq", "|": "par"}["|" if "|" in self.arrangement else ";"]
        first = self.arrangement.strip()[0]
        return f"{self.side}-{kind}-{first}-first" if kind == "seq" else f"{self.side}-{kind}"


ARRANGEMENT_ROWS: tuple[ArrangementRow, ...] = (
    ArrangementRow("receive", "a ; b", ("a", "b"), False,
                   "sequential receive: a blocked receive of a keeps b from being received"),
    ArrangementRow("receive", "b ; a", ("b", "a"), False,
                   "sequential receive in the other order: b is received first, then a"),
    ArrangementRow("receive", "a | b", None, True,
                   "parallel receive: b is received while the receive of a waits"),
    ArrangementRow("send", "a ; b", ("a", "b"), False,
                   "sequential send: b is not sent before a's consumer took a"),
    ArrangementRow("send", "b ; a", ("b", "a"), False,
                   "sequential send in the other order: b is sent first, then a"),
    ArrangementRow("send", "a | b", None, True,
                   "parallel send: b is sent (and taken) while the send of a waits"),
)


# ---------------------------------------------------------------------------- switching


@dataclass(frozen=True)
class SwitchRow:
    """The behaviours of specs `switching` (see systems.py): each row is one fact about the
    sequence of behaviours, their iterations and the conditions that ended them."""

    id: str
    statement: str


SWITCH_ROWS: tuple[SwitchRow, ...] = (
    SwitchRow("iterate-until-terminal",
              "a behaviour iterates until one of its terminal conditions holds, tested after "
              "each iteration: `first` (terminal n >= 3, n counting its iterations) runs "
              "exactly 3 iterations"),
    SwitchRow("switch-after-terminal",
              "switch conditions are evaluated only when the behaviour has ended: the switch "
              "`first -> never_taken when n >= 1` does not fire after the first iteration "
              "although its condition holds, because no terminal condition holds yet"),
    SwitchRow("switch-by-condition-name",
              "a switch condition names the terminal condition that ended the behaviour: "
              "`second` ends by `odd` (not `even`), so `switch second -> third when odd` is "
              "taken and `switch second -> first when even` is not"),
    SwitchRow("first-declared-wins",
              "when several `when` switches hold at once, the first declared is taken: "
              "`first` ends with both `first -> second when done` and the later "
              "`first -> shadowed when n >= 2` true, and goes to `second`"),
    SwitchRow("otherwise",
              "`otherwise` is taken when no other switch of the behaviour holds: `third` "
              "goes to `end`"),
    SwitchRow("memory-kept",
              "memory keeps its value from one behaviour to the next, and i counts on"),
    SwitchRow("end",
              "a switch to `end` ends the subsystem; the agent and the system then finish"),
)

SWITCH_SEQUENCE: tuple[tuple[str, str | None, str], ...] = (
    # (from, to, the condition that ended `from`)
    ("first", "second", "done"),
    ("second", "third", "odd"),
    ("third", None, "stop"),
)
SWITCH_ITERATIONS = {"first": 3, "second": 2, "third": 1}


# ---------------------------------------------------------------------------- ending


@dataclass(frozen=True)
class EndingRow:
    id: str
    statement: str


ENDING_ROWS: tuple[EndingRow, ...] = (
    EndingRow("error-condition-path",
              "an operation that fails (division by zero) in a behaviour with an error "
              "condition ends the behaviour through the error condition: its error "
              "conditions hold, the switch that names one is taken, and the failed partial "
              "function's target keeps its old value"),
    EndingRow("error-condition-by-value",
              "an error condition that holds by its own expression ends the behaviour like a "
              "terminal one, and the switches can tell which condition ended it"),
    EndingRow("failing-condition-is-an-error",
              "a terminal condition that fails to evaluate (division by zero) does not hold; "
              "the failure makes the behaviour's error conditions hold, so the switch that "
              "names the error condition is taken, not the terminal one's"),
    EndingRow("unhandled-failure-stops",
              "an operation that fails in a behaviour without an error condition stops the "
              "run with E802 (interpreter: the run ends with reason `error`; ROS 2: the node "
              "exits with code 1)"),
)


# ---------------------------------------------------------------------------- values


@dataclass(frozen=True)
class ValueRow:
    expr: str
    type: str                 # the memory variable's type
    value: bool | int | float | tuple[float, ...] | None   # None: it fails
    error: str | None = None  # the diagnostic code when it fails
    why: str = ""

    @property
    def id(self) -> str:
        return self.expr.replace(" ", "")


VALUE_ROWS: tuple[ValueRow, ...] = (
    ValueRow("7 % -3", "int", -2, why="% has the sign of the divisor"),
    ValueRow("-7 % 3", "int", 2, why="% has the sign of the divisor"),
    ValueRow("7 % 3", "int", 1),
    ValueRow("-7.5 % 2.0", "float", 0.5, why="float % has the sign of the divisor too"),
    ValueRow("7.5 % -2.0", "float", -0.5, why="float % has the sign of the divisor too"),
    ValueRow("7 / 2", "float", 3.5, why="/ is always true division"),
    ValueRow("-7 / 2", "float", -3.5, why="/ is always true division (no flooring)"),
    ValueRow("6 / 3", "float", 2.0, why="/ of two ints is a float"),
    ValueRow("10 - 4 - 3", "int", 3, why="binary operators associate to the left"),
    ValueRow("2 + 3 * 4", "int", 14, why="* binds tighter than +"),
    ValueRow("-2 * 3 + 1", "int", -5, why="unary minus binds tightest"),
    ValueRow("abs(-3)", "int", 3, why="abs of an int is an int"),
    ValueRow("min(1, 2.5)", "float", 1.0, why="min of an int and a float is a float"),
    ValueRow("clamp(5, 0, 3)", "int", 3),
    ValueRow("floor(-2.5)", "float", -3.0, why="floor rounds down, returns a float"),
    ValueRow("ceil(-2.5)", "float", -2.0, why="ceil rounds up, returns a float"),
    ValueRow("1 + 2 == 3 and not (2 < 1)", "bool", True),
    ValueRow("(0.5 + 0.25) * 4.0", "float", 3.0, why="the parenthesised sum first"),
    ValueRow("(1 + 2) / 2", "float", 1.5, why="an int sum, then true division"),
    ValueRow("2.0 * (once + 0.75) - 0.5", "float", 1.0,
             why="an int and a float in parentheses make a float"),
    ValueRow("false and 1 / once > 0.0", "bool", False,
             why="`and` does not evaluate its right side when the left is false"),
    ValueRow("true or 1 / once > 0.0", "bool", True,
             why="`or` does not evaluate its right side when the left is true"),
    ValueRow("true and 1 / once > 0.0", "bool", None, "E802",
             "the right side is evaluated when it decides, and its failure is an error"),
    ValueRow("false or once % 0 == 0", "bool", None, "E802",
             "the right side is evaluated when it decides, and its failure is an error"),
    ValueRow("(1 < 2) == (3 < 4)", "bool", True, why="comparisons' results compare as bools"),
    ValueRow("(2 < 1) == (3 < 4)", "bool", False, why="comparisons' results compare as bools"),
    ValueRow("(1 < 2) != (4 < 3)", "bool", True, why="comparisons' results compare as bools"),
    ValueRow("(1 == 1) != (2 == 3)", "bool", True, why="equalities' results compare as bools "
             "(no chained comparison)"),
    ValueRow("2.0 + (if once > 0 then 1.0 else 0.0)", "float", 2.0,
             why="a parenthesised `if` is one operand"),
    ValueRow("[10, 20, 30][once + 2]", "int", 30, why="indices run from 0"),
    ValueRow("[10, 20, 30][once - 1]", "int", None, "E802",
             "an index below 0 is out of range (not counted from the end)"),
    ValueRow("[10, 20, 30][once + 3]", "int", None, "E802", "an index past the end is an error"),
    ValueRow("if 1 > 2 then 1.0 else 2", "float", 2.0, why="the int branch widens to float"),
    ValueRow("[1.0, 2.0] + [3.0, 4.0]", "float[2]", (4.0, 6.0), why="element-wise"),
    ValueRow("[1.0, 2.0] * 2", "float[2]", (2.0, 4.0), why="array times number"),
    ValueRow("9223372036854775807 + 0", "int", 9223372036854775807, why="int is 64-bit"),
    ValueRow("9223372036854775807 + 1", "int", None, "E802", "int overflow is an error"),
    ValueRow("-9223372036854775807 - 2", "int", None, "E802", "int overflow is an error"),
    ValueRow("3037000500 * 3037000500", "int", None, "E802", "int overflow is an error"),
    ValueRow("abs(-9223372036854775807 - 1)", "int", None, "E802",
             "abs of the smallest int overflows"),
    ValueRow("1e308 * 10.0", "float", math.inf, why="float overflow gives inf"),
    ValueRow("inf - inf == inf - inf", "bool", False, why="NaN is unequal to itself"),
    ValueRow("min(inf - inf, 1.0)", "float", math.nan, why="min of a NaN is NaN"),
    ValueRow("max(1.0, inf - inf)", "float", math.nan, why="max of a NaN is NaN"),
    ValueRow("1 / 0", "float", None, "E802", "division by zero is an error, not inf"),
    ValueRow("1.0 / 0.0", "float", None, "E802", "division by zero is an error, not inf"),
    ValueRow("7 % 0", "int", None, "E802", "remainder by zero is an error"),
    ValueRow("7.5 % 0.0", "float", None, "E802", "remainder by zero is an error, not nan"),
    ValueRow("sqrt(-1.0)", "float", None, "E802", "a math domain error is an error, not nan"),
    ValueRow("log(0.0)", "float", None, "E802", "a math domain error is an error, not -inf"),
    ValueRow("once + 3", "0..3", 3, why="a range takes an int inside it"),
    ValueRow("once - 5", "-5..5", -5, why="a range with a negative low bound"),
    ValueRow("once + 4", "0..3", None, "E802", "an int stored outside its range is an error"),
    ValueRow("once - 6", "-5..5", None, "E802", "an int stored outside its range is an error"),
    ValueRow("[once, once + 9]", "0..3[2]", None, "E802",
             "an array stored into an array of ranges is checked element by element"),
)
