"""The specifications of the semantic tests, written for them (not the examples): small agents
built from templates, so that one agent can be put into a system of its own (interpreter,
verifier) or, with all the others, into the one system the ROS 2 tests build once.

Every producer here counts: its sample k carries the value k (data := n + 1, n the
iterations so far), so a value read names the sample it came from. Every consumer records,
per iteration, the value of its input and new() as its transition function saw them
(memory `seen` and `fresh`, a ring of SLOTS entries indexed by its iteration count k).
Frequencies are the defaults of the specs; the ROS 2 tests set them per node with the
parameter rssm.rate_hz.
"""

from __future__ import annotations

from pathlib import Path

from tests.semantics.expectations import Mode

SLOTS = 1024       # entries of the consumers' records (the interpreter runs stay below)


def _mode(m: Mode) -> str:
    return m.value


def mode_agent(name: str, producer: Mode, consumer: Mode, producer_hz: float = 10.0,
               consumer_hz: float = 10.0, slots: int = SLOTS) -> str:
    """Agent `name`: control subsystem c sends 1, 2, 3, ... to virtual effector `sink`."""
    return f"""
  // producer {producer.value}, consumer {consumer.value}
  agent {name} {{
    control c @ {producer_hz} Hz {{
      memory n: int = 0
      output data: int to e.sink {_mode(producer)}

      behaviour count {{
        update data {{ data := n + 1 }}
        update memory {{ n := n + 1 }}
        terminal never when false
        send data
      }}
      initial count
    }}

    effector sink @ {consumer_hz} Hz {{
      input data: int from c {_mode(consumer)}
      memory k: int = 0
      memory seen: int[{slots}]
      memory fresh: bool[{slots}]

      behaviour take {{
        update memory {{
          case new(data):
            seen[k % {slots}] := data
            fresh[k % {slots}] := true
            k := k + 1
          otherwise:
            seen[k % {slots}] := data
            fresh[k % {slots}] := false
            k := k + 1
        }}
        terminal never when false
        receive data
      }}
      initial take
    }}
  }}
"""


def receive_agent(name: str, arrangement: str, slow_hz: float = 5.0, fast_hz: float = 100.0,
                  consumer_hz: float = 50.0) -> str:
    """Agent `name`: control subsystem c receives a (from receptor ra, slow) and b (from
    receptor rb, fast) with blocking receives in the given arrangement."""
    return f"""
  // receive {arrangement}: a's producer slow, b's fast
  agent {name} {{
    control c @ {consumer_hz} Hz {{
      input a: int from r.ra blocking
      input b: int from r.rb blocking

      behaviour take {{
        terminal never when false
        receive {arrangement}
      }}
      initial take
    }}
{_counter("receptor", "ra", "a", "c", Mode.NONBLOCKING, slow_hz)}
{_counter("receptor", "rb", "b", "c", Mode.NONBLOCKING, fast_hz)}
  }}
"""


def send_agent(name: str, arrangement: str, slow_hz: float = 5.0, fast_hz: float = 100.0,
               producer_hz: float = 50.0) -> str:
    """Agent `name`: control subsystem c sends a (blocking, to effector ea, slow) and b
    (non-blocking, to effector eb, fast) in the given arrangement."""
    return f"""
  // send {arrangement}: a blocking to a slow consumer, b non-blocking to a fast one
  agent {name} {{
    control c @ {producer_hz} Hz {{
      memory n: int = 0
      output a: int to e.ea blocking
      output b: int to e.eb nonblocking

      behaviour give {{
        update a {{ a := n + 1 }}
        update b {{ b := n + 1 }}
        update memory {{ n := n + 1 }}
        terminal never when false
        send {arrangement}
      }}
      initial give
    }}
{_sink("ea", "a", Mode.BLOCKING, slow_hz)}
{_sink("eb", "b", Mode.NONBLOCKING, fast_hz)}
  }}
"""


def _counter(kind: str, name: str, buffer: str, peer: str, mode: Mode, hz: float) -> str:
    return f"""
    {kind} {name} @ {hz} Hz {{
      memory n: int = 0
      output {buffer}: int to {peer} {_mode(mode)}
      behaviour count {{
        update {buffer} {{ {buffer} := n + 1 }}
        update memory {{ n := n + 1 }}
        terminal never when false
      }}
      initial count
    }}"""


def _sink(name: str, buffer: str, mode: Mode, hz: float) -> str:
    return f"""
    effector {name} @ {hz} Hz {{
      input {buffer}: int from c {_mode(mode)}
      behaviour take {{
        terminal never when false
      }}
      initial take
    }}"""


def conditions_agent(name: str = "cond", producer_hz: float = 20.0,
                     consumer_hz: float = 20.0) -> str:
    """Agent `name`: c sends 1, 2, 3, ... (blocking) to effector w, which watches them
    (blocking) until one is >= 3, then switches to `after`, which records the first value it
    sees and new(data) in its first iteration."""
    return f"""
  // the terminal condition sees the value received in the same iteration
  agent {name} {{
    control c @ {producer_hz} Hz {{
      memory n: int = 0
      output data: int to e.w blocking
      behaviour count {{
        update data {{ data := n + 1 }}
        update memory {{ n := n + 1 }}
        terminal never when false
      }}
      initial count
    }}

    effector w @ {consumer_hz} Hz {{
      input data: int from c blocking
      memory first: int = -1
      memory first_new: bool = false

      behaviour watch {{
        terminal got3 when data >= 3
      }}
      behaviour after {{
        update memory {{
          case new(data):
            first_new := if first < 0 then true else first_new
            first := if first < 0 then data else first
          otherwise:
            first := if first < 0 then data else first
        }}
        terminal never when false
      }}
      initial watch
      switch watch -> after when got3
    }}
  }}
"""


# The control subsystems of the switching and error agents send a status (their iteration
# count) to a virtual effector `mon`: a subsystem with no channel at all hits a bug of the
# generated ROS 2 nodes (see test_nodecode.py / test_ros2.py, agent `solo`), and the rows of
# these agents are about switching, not about that.
_STATUS = "      output status: int to e.mon\n"


def _mon(hz: float) -> str:
    return f"""
    effector mon @ {hz} Hz {{
      input status: int from c
      behaviour watch {{
        terminal never when false
      }}
      initial watch
    }}"""


def switching_agent(name: str = "sw", hz: float = 50.0) -> str:
    """Agent `name`: behaviours first (3 iterations), second (2, ends by `odd`), third (1,
    `otherwise` to end); a behaviour `never_taken` whose switch condition holds after the
    first iteration of `first`, which has not ended then; a behaviour `shadowed` whose switch
    holds when `first` ends but is declared after the one to `second`."""
    return f"""
  // behaviour switching
  agent {name} {{
    control c @ {hz} Hz {{
      memory n: int = 0        // iterations of every behaviour (kept across switches)
      memory total: int = 0
{_STATUS}
      behaviour shadowed {{
        update memory {{ total := total + 1000 }}
        terminal t2 when true
      }}

      behaviour first {{
        update memory {{
          n := n + 1
          total := total + 1
        }}
        terminal done when n >= 3
      }}
      behaviour never_taken {{
        update memory {{ total := total + 100 }}
        terminal t when true
      }}
      behaviour second {{
        update memory {{
          n := n + 1
          total := total + 1
        }}
        terminal odd when n >= 5 and n % 2 == 1
        terminal even when n >= 5 and n % 2 == 0
      }}
      behaviour third {{
        update memory {{ total := total + 1 }}
        terminal stop when total >= 0
      }}

      initial first
      switch first -> never_taken when n == 1 and not done
      switch first -> second when done
      switch first -> shadowed when n >= 2
      switch never_taken -> end when t
      switch shadowed -> end when t2
      switch second -> first when even and not odd
      switch second -> third when odd
      switch third -> first when total < 0
      switch third -> end otherwise
    }}
{_mon(hz)}
  }}
"""


def error_agent(name: str = "errh", handled: bool = True, hz: float = 50.0) -> str:
    """Agent `name`: behaviour divide computes q := 12 / d, d := d - 1 from d = 2, so its
    third iteration divides by zero. With `handled`, divide has an error condition `failed`
    and switches to `check`, whose conditions tell whether the memory kept its old value."""
    error = "error failed when false" if handled else ""
    switch = ("switch divide -> check when failed\n      switch check -> end when kept\n"
              "      switch check -> end when changed and not kept" if handled else "")
    check = """
      behaviour check {
        terminal kept when d == 0 and q == 12.0
        error changed when not (d == 0 and q == 12.0)
      }""" if handled else ""
    return f"""
  // an operation fails: {"with" if handled else "without"} an error condition
  agent {name} {{
    control c @ {hz} Hz {{
      memory d: int = 2
      memory q: float = 0.0
{_STATUS}
      behaviour divide {{
        update memory {{
          q := 12 / d
          d := d - 1
        }}
        terminal never when d < -100 and q < 0.0
        {error}
      }}
{check}
      initial divide
      switch divide -> end when never
      {switch}
    }}
{_mon(hz)}
  }}
"""


def error_value_agent(name: str = "errv", hz: float = 50.0) -> str:
    """Agent `name`: behaviour watch has terminal `done` (n >= 10) and error `too_far`
    (n >= 3): the error condition ends it after 3 iterations, and the switch sees which."""
    return f"""
  // an error condition that holds by its expression
  agent {name} {{
    control c @ {hz} Hz {{
      memory n: int = 0
{_STATUS}
      behaviour watch {{
        update memory {{ n := n + 1 }}
        terminal done when n >= 10
        error too_far when n >= 3
      }}
      behaviour alarm {{
        update memory {{ n := n + 100 }}
        terminal t when true
      }}
      initial watch
      switch watch -> alarm when too_far and not done
      switch watch -> end when done
      switch alarm -> end when t
    }}
{_mon(hz)}
  }}
"""


def failing_condition_agent(name: str = "errt", hz: float = 50.0) -> str:
    """Agent `name`: behaviour divide counts d down from 2 and has the terminal condition
    `done when 10 / d < 0`, which fails to evaluate (division by zero) in its second
    iteration; its error condition `failed` (false by its expression) then holds, and the
    switch that names it is taken (not the one of `done`)."""
    return f"""
  // a terminal condition that fails to evaluate
  agent {name} {{
    control c @ {hz} Hz {{
      memory d: int = 2
{_STATUS}
      behaviour divide {{
        update memory {{ d := d - 1 }}
        terminal done when 10 / d < 0.0
        error failed when false
      }}
      behaviour check {{
        terminal kept when d == 0
      }}
      initial divide
      switch divide -> end when done
      switch divide -> check when failed
      switch check -> end when kept
    }}
{_mon(hz)}
  }}
"""


def solo_agent(name: str = "solo", hz: float = 50.0) -> str:
    """Agent `name`: one control subsystem without any channel, 3 iterations, then end."""
    return f"""
  // a subsystem without channels
  agent {name} {{
    control c @ {hz} Hz {{
      memory n: int = 0
      behaviour b {{
        update memory {{ n := n + 1 }}
        terminal done when n >= 3
      }}
      initial b
      switch b -> end when done
    }}
  }}
"""


def value_agent(expr: str, type_: str, name: str = "v") -> str:
    """Agent `name`: one iteration computes `r := expr`, then the subsystem ends."""
    return f"""
  agent {name} {{
    control c {{
      memory r: {type_}
      memory once: int = 0
      behaviour b {{
        update memory {{
          r := {expr}
          once := once + 1
        }}
        terminal done when once >= 1
      }}
      initial b
      switch b -> end when done
    }}
  }}
"""


def system(name: str, *agents: str) -> str:
    return f"// generated by tests/semantics/systems.py\nsystem {name} {{\n{''.join(agents)}}}\n"


def write(folder: Path, name: str, text: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.rssm"
    path.write_text(text, encoding="utf-8")
    return path


# ---------------------------------------------------------------------------- the ROS 2 system

MODE_AGENTS = {"bb": (Mode.BLOCKING, Mode.BLOCKING), "bn": (Mode.BLOCKING, Mode.NONBLOCKING),
               "nb": (Mode.NONBLOCKING, Mode.BLOCKING),
               "nn": (Mode.NONBLOCKING, Mode.NONBLOCKING)}
RECEIVE_AGENTS = {"rseq": "a ; b", "rrev": "b ; a", "rpar": "a | b"}
SEND_AGENTS = {"sseq": "a ; b", "srev": "b ; a", "spar": "a | b"}


def ros_system() -> str:
    """Every agent of the semantic tests in one system (one colcon build per session)."""
    agents = [mode_agent(a, p, c, slots=8) for a, (p, c) in MODE_AGENTS.items()]
    # a second non-blocking producer / blocking consumer pair, run at close rates
    agents.append(mode_agent("nbw", Mode.NONBLOCKING, Mode.BLOCKING, slots=8))
    agents += [receive_agent(a, arr) for a, arr in RECEIVE_AGENTS.items()]
    agents += [send_agent(a, arr) for a, arr in SEND_AGENTS.items()]
    agents += [conditions_agent(), switching_agent(), error_agent("errh", True),
               error_agent("erru", False), error_value_agent(), failing_condition_agent(),
               solo_agent()]
    return system("sem", *agents)
