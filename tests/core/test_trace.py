"""The trace format of rssm_core.trace: one writer, one reader, every kind of event."""

from __future__ import annotations

import json
import math
import shutil
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rssm_core.trace import (
    FORMAT_VERSION,
    SOURCE_INTERPRETER,
    SOURCE_NODE,
    Deadlock,
    End,
    Enter,
    Error,
    Event,
    Fire,
    Iteration,
    NodeEnter,
    NodeError,
    NodeSwitch,
    Other,
    Receive,
    Send,
    Stalled,
    Start,
    Switch,
    TraceFormatError,
    TraceWriter,
    encode,
    iter_events,
    parse_trace,
    read_trace,
    start_event,
)
from rssm_core.values import to_json
from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
from rssm_dsl.pipeline import compile_file

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
SPECS = ROOT / "tests" / "interp" / "specs"

INTERPRETER_EVENTS: list[Event] = [
    Start(system="s", mode="deterministic", seed=3, places=10, transitions=9, step=0, time=0.0,
          extra={"spec": "s.rssm", "replay": None}),
    Fire(transition="t[1,c,in]", role="structure", label="start", span="s.rssm:3:5",
         subsystem="a1.c", step=12, time=0.25),
    Fire(transition="t[1,c,cw,4]", forced=True, step=12, time=0.25),
    Fire(transition="t[in]"),                          # a hand-written firing sequence
    Enter(subsystem="a1.c", behaviour="cw", transition="t[1,c,alpha]", span="s.rssm:9:3",
          step=12, time=0.25),
    Enter(subsystem="a1.c", behaviour=None, transition="t[1,c,alpha]", span="s.rssm:9:3"),
    Switch(subsystem="a1.c", from_="cw", to="ccw", condition="done", conditions={"done": True},
           transition="t[1,c,2]", span="s.rssm:11:7", step=12, time=0.25),
    Switch(subsystem="a1.c", from_="ccw", to=None, condition="otherwise", conditions={},
           transition="t[1,c,3]", span="s.rssm:12:7", step=12, time=0.25),
    Send(subsystem="a1.c", buffer="cmd", channel="a1.c.cmd->a1.e.cmd", value=[1.0, "nan"],
         overwrote=False, place="p[1,c,cw,snd,1,op]", span="s.rssm:5:3", step=12, time=0.25),
    Receive(subsystem="a1.e", buffer="cmd", channel="a1.c.cmd->a1.e.cmd",
            value={"x": 1, "y": [True, False]}, place="p[1,e,go,rcv,1,op]", span="s.rssm:6:3",
            step=12, time=0.25),
    Error(code="E802", message="boom", span="s.rssm:7:9", subsystem=None, place="p[1,c,2]",
          handled=False, step=12, time=0.25),
    Deadlock(marking=["p[1,c,in]"], waiting={"a1.c": "p[1,c,in]"}, step=12, time=0.25),
    Stalled(waiting={"a1.c": "p[1,c,run,snd,1,wait]"}, step=40, time=1.0),
    End(reason="finished", message="the system finished", problems=[],
        summary={"steps": 12, "subsystems": []}, step=12, time=0.25),
    Other(name="behaviour", extra={"subsystem": "a1.c", "behaviour": "cw"}),
]
NODE_EVENTS: list[Event] = [
    Start(source=SOURCE_NODE),
    NodeEnter(from_=None, to="cw", i=0, conditions={}),
    Iteration(i=1, behaviour="cw", new=[True, False], cases=[3, 0], sent={"cmd": 4},
              received={"pos": {"seq": 7, "value": [0.5, "inf"]}}, conditions={"done": False},
              t=0.0125),
    NodeError(i=2, behaviour="cw", code="E802", message="division by zero", where="s.rssm:4:9",
              handled=True),
    NodeSwitch(from_="cw", to="ccw", i=2, conditions={"done": True}),
    NodeSwitch(from_="ccw", to=None, i=9, conditions={"stop": True}),
]


def write(path: Path, events: list[Event] | list[dict[str, Any]]) -> Path:
    with TraceWriter(path) as w:
        for e in events:
            w.emit(e)
    return path


@pytest.mark.parametrize("events", [INTERPRETER_EVENTS, NODE_EVENTS],
                         ids=["interpreter", "node"])
def test_round_trip_gives_the_same_events(tmp_path: Path, events: list[Event]) -> None:
    trace = read_trace(write(tmp_path / "t.jsonl", events))
    assert list(trace.events) == events
    assert [e.line for e in trace.events] == list(range(1, len(events) + 1))
    assert trace.header == events[0] and trace.format == FORMAT_VERSION
    assert isinstance(events[0], Start) and trace.source == events[0].source
    # and the objects written are what to_json says, line by line
    lines = (tmp_path / "t.jsonl").read_text().splitlines()
    assert [json.loads(x) for x in lines] == [e.to_json() for e in events]


def test_the_same_kind_means_the_source_s_event() -> None:
    node = parse_trace([json.dumps(start_event(SOURCE_NODE)),
                        '{"event":"switch","from":"a","to":null,"i":3,"conditions":{}}'])
    interp = parse_trace([json.dumps(start_event(SOURCE_INTERPRETER, system="s")),
                          '{"event":"switch","subsystem":"a1.c","from":"a","to":null,'
                          '"condition":"x","conditions":{},"transition":"t","span":"f:1:1"}'])
    assert isinstance(node.events[1], NodeSwitch) and node.source == SOURCE_NODE
    assert isinstance(interp.events[1], Switch) and interp.source == SOURCE_INTERPRETER
    # without a header (node traces written before format 1): the "i" of the first event
    old = parse_trace(['{"event":"enter","from":null,"to":"a","i":0,"conditions":{}}',
                       '{"event":"switch","from":"a","to":null,"i":3,"conditions":{}}'])
    assert old.header is None and old.source == SOURCE_NODE
    assert [type(e) for e in old.events] == [NodeEnter, NodeSwitch]
    fires = parse_trace(['{"event":"fire","transition":"t[in]"}'])
    assert fires.source == SOURCE_INTERPRETER and fires.fires()[0].transition == "t[in]"


def test_start_line_has_the_format_version() -> None:
    assert start_event(SOURCE_INTERPRETER, system="s") == {
        "event": "start", "format": FORMAT_VERSION, "source": "interpreter", "system": "s"}
    with pytest.raises(ValueError):
        start_event("robot")
    # a header written before the version field: format 1, from the interpreter
    old = parse_trace(['{"event":"start","system":"s","mode":"deterministic","seed":0,'
                       '"places":3,"transitions":2,"step":0,"time":0.0}'])
    assert old.format == 1 and old.source == SOURCE_INTERPRETER
    assert old.header is not None and old.header.system == "s"


@pytest.mark.parametrize(("lines", "line", "message"), [
    (['{"event":"fire","transition":"a"}', "not json"], 2, "not JSON"),
    (['{"event":"fire","transition":"a"}', "", "[1, 2]"], 3, "not a JSON object (found a list)"),
    (['{"event":"fire","transition":3}'], 1, '"transition" of a fire event must be a string'),
    (['{"event":"fire"}'], 1, 'fire event without "transition"'),
    (['{"transition":"a"}'], 1, 'no "event" string'),
    (['{"event":7}'], 1, '"event" is not a string'),
    (['{"event":"fire","transition":"a","forced":"yes"}'], 1, "must be true or false"),
    (['{"event":"fire","transition":"a","step":1.5}'], 1, '"step" of a fire event must be an '
                                                          "integer"),
    (['{"event":"fire","transition":"a","time":true}'], 1, "must be a number"),
    (['{"event":"start","format":1,"source":"interpreter"}', "",
      '{"event":"start","format":1,"source":"interpreter"}'], 3, "after the first line"),
    (['{"event":"start","format":2,"source":"interpreter"}'], 1, "trace format 2 is not "
                                                                 "supported"),
    (['{"event":"start","format":1,"source":"robot"}'], 1, 'unknown trace source "robot"'),
    (['{"event":"deadlock","marking":["a",1],"waiting":{}}'], 1, "a list of strings"),
    (['{"event":"start","format":1,"source":"node"}',
      '{"event":"iteration","i":1,"behaviour":"b","new":[],"cases":[],"sent":{},'
      '"received":{"x":{"value":1}},"conditions":{},"t":0}'], 2, '"received" of a iteration'),
    (['{"event":"start","format":1,"source":"node"}',
      '{"event":"enter","subsystem":"a1.c","behaviour":"b"}'], 2, 'enter event without "from"'),
    ([b'{"event":"fire","transition":"a"}\n', b'{"event":"fire","transition":"\xff"}\n'], 2,
     "not UTF-8"),
])
def test_a_malformed_line_is_an_error_naming_it(lines: list[str | bytes], line: int,
                                                message: str) -> None:
    with pytest.raises(TraceFormatError) as e:
        parse_trace(lines, "run.jsonl")
    assert e.value.line == line
    assert message in e.value.message
    assert str(e.value).startswith(f"run.jsonl:{line}: ")


def test_the_reader_stops_at_the_first_bad_line_and_reads_files(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl"
    path.write_text('{"event":"fire","transition":"a"}\n\n{"event":"fire","transition":"b"}\n'
                    '{"event":"fire"\n')
    events = iter_events(path.read_text().split("\n"), str(path))
    assert [e.line for e in (next(events), next(events))] == [1, 3]
    with pytest.raises(TraceFormatError, match=r"t\.jsonl:4: not JSON"):
        next(events)
    with pytest.raises(TraceFormatError) as e:
        read_trace(path)
    assert e.value.line == 4 and e.value.source == str(path)


def test_unknown_kinds_and_fields_are_kept() -> None:
    trace = parse_trace(['{"event":"fire","transition":"a","why":"later field"}',
                         '{"event":"pause","seconds":3}'])
    fire, other = trace.events
    assert isinstance(fire, Fire) and fire.extra == {"why": "later field"}
    assert isinstance(other, Other) and other.kind == "pause" and other.extra == {"seconds": 3}
    assert [e.to_json() for e in trace.events] == [
        {"event": "fire", "transition": "a", "why": "later field"},
        {"event": "pause", "seconds": 3}]


def test_values_are_encoded_the_one_way() -> None:
    value = {"a": float("nan"), "b": [float("inf"), -math.inf, 1.5],
             "c": np.array([1.0, np.nan]), "d": np.float32(2.5), "e": np.int64(7),
             "f": (np.bool_(True), np.float64(-np.inf))}
    line = encode({"event": "send", "value": value, "time": np.float64(0.5)})
    assert "NaN" not in line and "Infinity" not in line
    assert json.loads(line) == {"event": "send", "value": to_json(value), "time": 0.5}
    assert json.loads(line)["value"] == {"a": "nan", "b": ["inf", "-inf", 1.5],
                                         "c": [1.0, "nan"], "d": 2.5, "e": 7,
                                         "f": [True, "-inf"]}
    # a non-finite float outside any value is encoded the same way
    assert json.loads(encode({"event": "x", "t": float("nan")})) == {"event": "x", "t": "nan"}


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(
    st.text(min_size=1, max_size=8), st.booleans(),
    st.recursive(st.none() | st.booleans() | st.integers() | st.text(max_size=5)
                 | st.floats(allow_nan=False, allow_infinity=False),
                 lambda inner: st.lists(inner, max_size=3)
                 | st.dictionaries(st.text(max_size=4), inner, max_size=3), max_leaves=8)),
    max_size=12))
def test_round_trip_of_random_events(rows: list[tuple[str, bool, Any]]) -> None:
    events: list[Event] = [Start(system="s")]
    for k, (name, forced, value) in enumerate(rows):
        events.append(Fire(transition=name, forced=forced, step=k, time=k / 8))
        events.append(Send(subsystem="a1.c", buffer=name, channel="ch", value=value,
                           overwrote=forced, place="p", span="f:1:1", step=k))
    lines = [encode(e) for e in events]
    assert list(parse_trace(lines).events) == events


def test_the_writer_batches_flushes_and_is_thread_safe(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl"
    w = TraceWriter(path, batch=1000, flush_every=0.0)      # a node: on disk at once
    w.emit(start_event(SOURCE_NODE))
    assert path.read_text().count("\n") == 1
    w.close()
    assert w.closed
    w = TraceWriter(path, batch=7)

    def worker(k: int) -> None:
        for i in range(200):
            w.emit({"event": "fire", "transition": f"t{k}-{i}"})

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    w.close()
    names = [f.transition for f in read_trace(path).fires()]
    assert w.count == 800 and len(names) == 800
    assert sorted(names) == sorted(f"t{k}-{i}" for k in range(4) for i in range(200))


def _traced_run(tmp_path: Path, spec: Path, **options: Any) -> Path:
    comp = compile_file(spec)
    assert comp.ok
    rt = build_runtime(comp, RunConfig(base_dir=spec.parent))
    rt.tracer = TraceWriter(tmp_path / f"{spec.stem}.jsonl")
    Simulator(rt, SimOptions(seed=1, **options)).run()
    rt.tracer.close()
    return tmp_path / f"{spec.stem}.jsonl"


def test_what_the_interpreter_writes_is_read_back_exactly(tmp_path: Path) -> None:
    """Real runs: behaviour switches and channel values (camera), handled operation failures
    (faulty), a deadlock (handshake), a stall (starve); every line is valid and typed, to_json
    gives it back."""
    for name in ("camera_tracker.rssm", "camera.csv"):
        shutil.copy(EXAMPLES / name, tmp_path / name)
    shutil.copytree(SPECS, tmp_path / "specs")
    paths = [_traced_run(tmp_path, tmp_path / "camera_tracker.rssm", until=1.5),
             _traced_run(tmp_path, tmp_path / "specs" / "faulty.rssm", max_steps=100_000),
             _traced_run(tmp_path, tmp_path / "specs" / "handshake_deadlock.rssm",
                         max_steps=10_000),
             _traced_run(tmp_path, tmp_path / "specs" / "starve.rssm", until=10.0)]
    kinds: set[type[Event]] = set()
    for path in paths:
        trace = read_trace(path)
        raw = [json.loads(x) for x in path.read_text().splitlines()]
        assert [e.to_json() for e in trace.events] == raw
        assert trace.header is not None and trace.header.format == FORMAT_VERSION
        assert trace.source == SOURCE_INTERPRETER and trace.header.seed == 1
        assert isinstance(trace.events[-1], End)
        assert all(isinstance(e, Start | Fire | Enter | Switch | Send | Receive | Error
                              | Deadlock | Stalled | End) for e in trace.events)
        kinds.update(type(e) for e in trace.events)
    assert kinds == {Start, Fire, Enter, Switch, Send, Receive, Error, Deadlock, Stalled, End}


@pytest.mark.parametrize("text", [
    '{"event":"fire","transition":"t[in]"}\n{"event":"fire","transition":3}\n',
    '{"event":"fire","transition":"t[in]"}\n\n{"event":"start","format":1,"source":"node"}\n',
    '{"event":"start","format":9,"source":"interpreter"}\n{"event":"fire","transition":"x"}\n',
])
def test_replay_and_playback_read_traces_with_the_one_reader(tmp_path: Path, text: str) -> None:
    """The same malformed line is the same error, at the same line, for `simulate --replay`
    and for the explorer's playback."""
    from rssm_dsl.diagnostics import DiagnosticBag
    from rssm_dsl.interp.replay import ReplayFileError, load_counterexample
    from rssm_dsl.render.playback import read_firings

    path = tmp_path / "t.jsonl"
    path.write_text(text)
    with pytest.raises(TraceFormatError) as core:
        read_trace(path)
    with pytest.raises(ReplayFileError) as replay:
        load_counterexample(path)
    assert str(replay.value) == str(core.value)
    bag = DiagnosticBag()
    assert read_firings(path, bag) is None
    (d,) = bag.items
    assert d.code == "E852" and d.span.line == core.value.line
    assert core.value.message in d.message


def test_replay_and_playback_take_the_fire_events(tmp_path: Path) -> None:
    from rssm_dsl.diagnostics import DiagnosticBag
    from rssm_dsl.interp.replay import load_counterexample
    from rssm_dsl.render.playback import read_firings

    path = write(tmp_path / "t.jsonl", INTERPRETER_EVENTS)
    names = [f.transition for f in read_trace(path).fires()]
    assert names == ["t[1,c,in]", "t[1,c,cw,4]", "t[in]"]
    assert list(load_counterexample(path).steps) == names
    read = read_firings(path, DiagnosticBag())
    assert read is not None and [(f.transition, f.line) for f in read[1]] == [
        (f.transition, f.line) for f in read_trace(path).fires()]
