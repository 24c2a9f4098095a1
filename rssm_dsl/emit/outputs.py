"""`rssmc compile`'s outputs written all or nothing (rssm_dsl/emit/write.py), each file
staged as it is made, and on a large net made on two cores.

Each output is streamed: its text is written to the staging folder piece by piece and never
held whole (the JSON IR of 5,000 agents is 150 MB). On a large net the outputs are split in
two groups of about the same cost: a forked child makes and stages one group while this
process makes the other (they share the compiled net, copied on write; the collector's
objects are frozen first so that no collection in the child touches them all). The child
reports the names it staged, or the error it met, through a pipe; the error of the first
output (in the order asked) that failed is raised, as making them one after the other would
have raised it, and nothing is moved into place unless every output was staged.
"""

from __future__ import annotations

import gc
import os
import pickle
import signal
import sys
import traceback
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from rssm_dsl.emit.cpn import emit_cpn
from rssm_dsl.emit.dot import stream_dot
from rssm_dsl.emit.dump import stream_dump
from rssm_dsl.emit.json_ir import stream_json
from rssm_dsl.emit.pnml import emit_paged_pnml, stream_pnml
from rssm_dsl.emit.write import Staging
from rssm_dsl.filenames import UnusableFileName
from rssm_dsl.hpn.ir import HPN
from rssm_dsl.semantics.model import System

Files = Iterator[tuple[str, Iterable[str]]]
Stream = Callable[[HPN, System | None], Files]


def _whole(emit: Callable[[HPN], dict[str, str]]) -> Stream:
    def stream(hpn: HPN, system: System | None) -> Files:
        yield from emit(hpn).items()
    return stream


def _mcc(hpn: HPN, system: System | None) -> Files:
    from rssm_dsl.emit.mcc import emit_mcc

    # mcc also writes the spec's properties: it needs the checked system
    yield from emit_mcc(hpn, system).items()


# --emit name -> its files, each text in pieces (the same text as rssm_dsl.emit.EMITTERS)
STREAMS: dict[str, Stream] = {
    "json": lambda hpn, _: stream_json(hpn),
    "dump": lambda hpn, _: stream_dump(hpn),
    "dot": lambda hpn, _: stream_dot(hpn),
    "pnml": lambda hpn, _: stream_pnml(hpn),
    "pnml-paged": _whole(emit_paged_pnml),
    "cpn": _whole(emit_cpn),
    "mcc": _mcc,
}

# the relative cost of each output on a large net (seconds of CPU for 5,000 small agents,
# as measured in the two processes: writing and the copies on write included), to split
# them in two groups of about the same cost
COST: dict[str, float] = {"json": 1.0, "pnml": 1.8, "dot": 0.55, "dump": 0.45,
                          "pnml-paged": 1.5, "cpn": 2.0, "mcc": 1.8}

# a net smaller than this (places, transitions and arcs) is written by one process: a fork
# costs more than it saves
PARALLEL_SIZE = 50_000


def write_compiled(target: Path, kinds: list[str], hpn: HPN, system: System | None,
                   parallel: bool | None = None) -> list[Path]:
    """Make the outputs ``kinds`` (STREAMS' names) of ``hpn`` and move them into
    ``target`` together (rssm_dsl.emit.write). ``parallel``: on two processes (None: when
    the net is large and the machine has two cores). Returns the paths written."""
    kinds = list(dict.fromkeys(kinds))
    if parallel is None:
        parallel = _worth_a_fork(hpn, kinds)
    with Staging(target) as staging:
        if parallel and len(kinds) > 1:
            _stage_on_two(staging, kinds, hpn, system)
        else:
            for k in kinds:
                _stage(staging, k, hpn, system)
        return staging.commit()


def _stage(staging: Staging, kind: str, hpn: HPN, system: System | None) -> None:
    for rel, pieces in STREAMS[kind](hpn, system):
        staging.write(rel, pieces)


def _worth_a_fork(hpn: HPN, kinds: list[str]) -> bool:
    if not hasattr(os, "fork") or len(kinds) < 2:
        return False
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return (cores or 1) > 1 and len(hpn.places) + len(hpn.transitions) + len(hpn.arcs) \
        >= PARALLEL_SIZE


def split(kinds: list[str]) -> tuple[list[str], list[str]]:
    """The outputs this process makes and those the child makes: the costliest first, each
    to the group that costs less so far (this process's on a tie: it starts at once)."""
    mine: list[str] = []
    child: list[str] = []
    cost = [0.0, 0.0]
    for k in sorted(kinds, key=lambda k: -COST.get(k, 1.0)):
        side = 0 if cost[0] <= cost[1] else 1
        (mine if side == 0 else child).append(k)
        cost[side] += COST.get(k, 1.0)
    return [k for k in kinds if k in mine], [k for k in kinds if k in child]


# what a group's run ends with: the names it staged, or the position (in the order asked)
# of the output that failed and its error
_Outcome = tuple[list[str], int | None, BaseException | None]


def _run(staging: Staging, group: list[str], kinds: list[str], hpn: HPN,
         system: System | None) -> _Outcome:
    for k in group:
        try:
            _stage(staging, k, hpn, system)
        except Exception as e:
            return staging.names, kinds.index(k), e
    return staging.names, None, None


def _stage_on_two(staging: Staging, kinds: list[str], hpn: HPN,
                  system: System | None) -> None:
    mine, theirs = split(kinds)
    staging.folder()                      # made before the child, which writes into it
    hpn.index()                           # (most outputs read it: made once, shared)
    for stream in (sys.stdout, sys.stderr):
        stream.flush()                    # (not written twice by the child's copy)
    gc.freeze()
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:                          # the child: stage, report, end at once
        os.close(read)
        _child(write, staging, theirs, kinds, hpn, system)
    gc.unfreeze()
    os.close(write)
    status: int | None = None             # the child's, once it has ended
    try:
        _, failed, error = _run(staging, mine, kinds, hpn, system)
        data = _read_all(read)
        status = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
    finally:
        os.close(read)
        if status is None:                # interrupted: the child is stopped before the
            _stop(pid)                    # staging folder is removed
    their_names, their_failed, their_error = _outcome(data, status)
    staging.add(their_names)
    failures = [(i, e) for i, e in ((failed, error), (their_failed, their_error))
                if i is not None and e is not None]
    if failures:
        raise min(failures, key=lambda f: f[0])[1]


def _child(write: int, staging: Staging, group: list[str], kinds: list[str], hpn: HPN,
           system: System | None) -> None:
    """Stage ``group``, send the outcome to the parent and end, without the interpreter's
    teardown (it is the parent's process image: its files, atexit handlers and buffers are
    the parent's)."""
    status = 1
    try:
        staging.names = []
        names, failed, error = _run(staging, group, kinds, hpn, system)
        if error is not None and os.environ.get("RSSMC_DEBUG"):
            traceback.print_exception(error)
            sys.stderr.flush()
        with os.fdopen(write, "wb") as out:
            out.write(_dumps((names, failed, error)))
        status = 0
    finally:
        os._exit(status)


def _dumps(outcome: _Outcome) -> bytes:
    """The outcome pickled; an error that does not survive pickling is sent as one that
    reads the same (rssm_dsl.commands.common.guarded reports an error by its type: a file
    name that cannot be one, or another, by its type's name and message)."""
    names, failed, error = outcome
    try:
        data = pickle.dumps(outcome)
        pickle.loads(data)
        return data
    except Exception:
        stand_in: BaseException = (
            _Unusable(error.name, error.reason) if isinstance(error, UnusableFileName)
            else _Unpicklable(type(error).__name__, str(error)))
        return pickle.dumps((names, failed, stand_in))


class _Unusable(Exception):
    """An UnusableFileName of the child, by its arguments."""

    def __init__(self, name: str, reason: str) -> None:
        super().__init__(name, reason)


class _Unpicklable(Exception):
    """Another error of the child that could not be sent as it was: its type's name and
    its message."""

    def __init__(self, name: str, message: str) -> None:
        super().__init__(name, message)


def _restored(error: BaseException | None) -> BaseException | None:
    """The error the child met, from what it sent."""
    if isinstance(error, _Unusable):
        return UnusableFileName(*error.args)
    if isinstance(error, _Unpicklable):
        name, message = error.args
        return type(name, (Exception,), {})(message)  # type: ignore[no-any-return]
    return error


def _read_all(read: int) -> bytes:
    """What the child sent, up to its end of the pipe being closed (when it ends)."""
    chunks: list[bytes] = []
    while chunk := os.read(read, 1 << 16):
        chunks.append(chunk)
    return b"".join(chunks)


def _outcome(data: bytes, status: int) -> _Outcome:
    """The child's outcome, from what it sent and how it ended (an error if it ended
    without sending one)."""
    if status != 0 or not data:
        raise RuntimeError(f"the process writing outputs ended with status {status}")
    names, failed, error = pickle.loads(data)
    return names, failed, _restored(error)


def _stop(pid: int) -> None:
    """End the child and wait for it."""
    try:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
    except OSError:
        pass
