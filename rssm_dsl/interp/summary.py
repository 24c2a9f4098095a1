"""What the user sees of a run: the current behaviour of every subsystem, its iteration
counters, the state of every channel; as data (:class:`Snapshot`, also written to the trace)
and as text (:func:`render`), shown live while the run goes and once at its end."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from rssm_core.records import dataclass
from rssm_dsl.interp.values import short

if TYPE_CHECKING:
    from rssm_dsl.interp.engine import TokenGame
    from rssm_dsl.interp.program import Runtime


@dataclass(frozen=True)
class SubsystemView:
    id: str
    behaviour: str | None
    state: str                  # "starting" | "running" | "ended"
    i: int                      # discrete time stamp (iterations of every behaviour)
    iterations: dict[str, int]  # per behaviour
    switches: int
    overruns: int
    handled_errors: int


@dataclass(frozen=True)
class DeviceView:
    id: str
    steps: int
    overruns: int


@dataclass(frozen=True)
class ChannelView:
    id: str
    modes: str
    state: str                  # "full" | "empty"
    sent: int
    received: int
    overwritten: int
    value: str


@dataclass(frozen=True)
class Snapshot:
    system: str
    steps: int
    time: float
    subsystems: tuple[SubsystemView, ...]
    devices: tuple[DeviceView, ...]
    channels: tuple[ChannelView, ...]

    def to_json(self) -> dict[str, Any]:
        return {
            "steps": self.steps, "time": self.time,
            "subsystems": [s.__dict__ for s in self.subsystems],
            "devices": [d.__dict__ for d in self.devices],
            "channels": [c.__dict__ for c in self.channels],
        }

    def subsystem(self, id: str) -> SubsystemView:
        return next(s for s in self.subsystems if s.id == id)

    def channel(self, id: str) -> ChannelView:
        return next(c for c in self.channels if c.id == id)


def _full_places(rt: Runtime) -> dict[str, int]:
    """Flat index of the `full` fused place of each channel."""
    out: dict[str, int] = {}
    for p in rt.net.places:
        fs = rt.hpn.fusions.get(p.name)
        if p.channel is not None and fs is not None and fs.key is not None and fs.key.full:
            out[p.channel] = p.index
    return out


def snapshot(rt: Runtime, game: TokenGame, steps: int) -> Snapshot:
    subs = []
    for s in rt.subsystems.values():
        state = "ended" if s.ended else ("running" if s.started else "starting")
        subs.append(SubsystemView(
            s.id, s.behaviour, state, s.i,
            {name: b.iterations for name, b in s.behaviours.items()}, s.switches,
            s.ticker.overruns if s.ticker is not None else 0, s.handled_errors))
    devs = [DeviceView(d.id, d.steps, d.ticker.overruns if d.ticker is not None else 0)
            for d in rt.devices.values()]
    full = _full_places(rt)
    chans = []
    for ch in rt.channels.values():
        p = full.get(ch.id)
        state = "full" if p is not None and game.tokens[p] else "empty"
        chans.append(ChannelView(ch.id, ch.channel.modes, state, ch.sent, ch.received,
                                 ch.overwritten, short(ch.value) if ch.sent else "-"))
    return Snapshot(rt.system.name, steps, rt.time(), tuple(subs), tuple(devs), tuple(chans))


def render(s: Snapshot, wall: float | None = None) -> str:
    rate = f", {s.steps / wall:,.0f} firings/s" if wall else ""
    lines = [f"system {s.system}: {s.steps:,} firings, t = {s.time:.6g} s{rate}"]
    if s.subsystems:
        width = max(len(x.id) for x in s.subsystems)
        for x in s.subsystems:
            where = x.behaviour if x.behaviour is not None else f"({x.state})"
            counts = " ".join(f"{b}={n}" for b, n in x.iterations.items())
            extra = f", {x.switches} switches" if x.switches else ""
            extra += f", {x.overruns} overruns" if x.overruns else ""
            extra += f", {x.handled_errors} errors handled" if x.handled_errors else ""
            lines.append(f"  {x.id:<{width}}  {where:<12} i={x.i:<8} [{counts}]{extra}")
    for d in s.devices:
        over = f", {d.overruns} overruns" if d.overruns else ""
        lines.append(f"  device {d.id}: {d.steps} steps{over}")
    for c in s.channels:
        lost = f", {c.overwritten} overwritten" if c.overwritten else ""
        lines.append(f"  {c.id} [{c.modes}] {c.state:<5} sent {c.sent} received "
                     f"{c.received}{lost}  last {c.value}")
    return "\n".join(lines)
