"""Pair buffers into channels and check the links the methodology allows (paper III-A).

A buffer of a designed subsystem names its peer relative to its agent: `c`, `e.NAME`,
`r.NAME`, `E.NAME`, `R.NAME`, or `AGENT.c` for another agent's control subsystem; a
trailing `.BUFFER` picks one buffer of the peer when several could match.
Allowed links: c-e, c-r, e-E, r-R inside an agent, and c-c between agents (T buffers).
"""

from __future__ import annotations

from dataclasses import replace

from rssm_dsl.diagnostics import DiagnosticBag, Related
from rssm_dsl.semantics.model import Buffer, Channel
from rssm_dsl.semantics.structure import AgentShell, Shell
from rssm_dsl.syntax import ast

_ALLOWED = {frozenset("ce"), frozenset("cr"), frozenset("eE"), frozenset("rR")}
_LETTERS = {"c", "e", "r", "E", "R"}


def _link_allowed(a: Shell, b: Shell) -> bool:
    if a.agent != b.agent:
        return a.letter == "c" and b.letter == "c"
    return frozenset((a.letter, b.letter)) in _ALLOWED


class ChannelPass:
    def __init__(self, bag: DiagnosticBag, agents: list[AgentShell]) -> None:
        self.bag = bag
        self.agents = {a.name: a for a in agents}
        self.by_id = {s.id: s for a in agents for s in a.shells}

    def _resolve(self, owner: Shell, peer: ast.PeerRef, report: bool = True
                 ) -> tuple[Shell, str | None] | None:
        bag = self.bag if report else DiagnosticBag()
        parts = list(peer.parts)
        agent = owner.agent
        if parts[0] not in _LETTERS and parts[0] in self.agents and len(parts) >= 2:
            agent = parts.pop(0)
            if parts[0] != "c":
                bag.error("E302", f"'{peer}': between agents only control subsystems talk "
                               f"(write `{agent}.c`)", peer.span)
                return None
        letter = parts[0]
        if letter not in _LETTERS:
            bag.error("E303", f"'{peer}' is not a subsystem", peer.span,
                           "name a peer as c, e.NAME, r.NAME, E.NAME, R.NAME or AGENT.c")
            return None
        if letter == "c":
            target_id, rest = f"{agent}.c", parts[1:]
        elif len(parts) < 2:
            bag.error("E303", f"'{peer}': which {letter}? write {letter}.NAME", peer.span)
            return None
        else:
            target_id, rest = f"{agent}.{letter}.{parts[1]}", parts[2:]
        target = self.by_id.get(target_id)
        if target is None:
            bag.error("E303", f"{target_id} does not exist", peer.span,
                           f"declare it in agent '{agent}'" if agent in self.agents
                           else f"there is no agent '{agent}'")
            return None
        if len(rest) > 1:
            bag.error("E303", f"'{peer}' has too many parts", peer.span)
            return None
        if target is owner:
            bag.error("E302", f"{owner.id} cannot talk to itself", peer.span)
            return None
        return target, (rest[0] if rest else None)

    def _points_back(self, candidate: Buffer, holder: Shell, owner: Shell, owner_buf: Buffer
                     ) -> bool:
        """Does `candidate` (a buffer of `holder`) name `owner` (and `owner_buf`) as its peer?"""
        if holder.device:
            return True
        ref = holder.peers.get(candidate.name)
        resolved = self._resolve(holder, ref, report=False) if ref is not None else None
        return (resolved is not None and resolved[0] is owner
                and resolved[1] in (None, owner_buf.name))

    def run(self) -> list[Channel]:
        pairs: dict[tuple[str, str], tuple[Buffer, Buffer]] = {}
        for shell in self.by_id.values():
            if shell.device:
                continue
            for buf in shell.buffers:
                ref = shell.peers.get(buf.name)
                if ref is None:
                    continue
                resolved = self._resolve(shell, ref)
                if resolved is None:
                    continue
                peer, wanted = resolved
                if not _link_allowed(shell, peer):
                    self.bag.error(
                        "E302", f"{shell.id} cannot be linked to {peer.id}", ref.span,
                        "allowed links: c-e, c-r, e-E, r-R inside an agent, c-c between agents",
                    )
                    continue
                partner = self._partner(shell, buf, peer, wanted, ref)
                if partner is None:
                    continue
                prod, cons = (buf, partner) if buf.direction is ast.Direction.OUTPUT else (partner, buf)
                pairs[(prod.qualified, cons.qualified)] = (prod, cons)
        return self._finish(pairs)

    def _partner(self, shell: Shell, buf: Buffer, peer: Shell, wanted: str | None,
                 ref: ast.PeerRef) -> Buffer | None:
        opposite = (ast.Direction.INPUT if buf.direction is ast.Direction.OUTPUT
                    else ast.Direction.OUTPUT)
        if wanted is not None:
            found = next((b for b in peer.buffers if b.name == wanted), None)
            if found is None or found.direction is not opposite:
                self.bag.error("E304", f"{peer.id} has no {opposite.value} buffer '{wanted}'",
                               ref.span)
                return None
            candidates = [found]
        else:
            candidates = [b for b in peer.buffers if b.direction is opposite
                          and self._points_back(b, peer, shell, buf)]
            if peer.device and len(candidates) > 1:
                same = [b for b in candidates if b.name == buf.name]
                candidates = same or candidates
        if not candidates:
            word = "to" if opposite is ast.Direction.OUTPUT else "from"
            self.bag.error(
                "E304", f"{buf.direction.value} '{buf.name}' of {shell.id} has no matching "
                f"{opposite.value} buffer on {peer.id}", buf.span,
                f"declare `{opposite.value} NAME: {buf.type} {word} {_relative(shell, peer)}` in "
                f"{peer.id}" if not peer.device else f"device {peer.device_type} has no "
                f"{opposite.value} buffer",
            )
            return None
        if len(candidates) > 1:
            names = ", ".join(b.name for b in candidates)
            self.bag.error("E306", f"several buffers of {peer.id} could match '{buf.name}': "
                           f"{names}", ref.span, f"write `{ref}.BUFFER`, e.g. `{ref}."
                           f"{candidates[0].name}`")
            return None
        partner = candidates[0]
        if partner.type != buf.type:
            self.bag.error("E305", f"'{buf.name}' is {buf.type} but its peer buffer "
                           f"{partner.qualified} is {partner.type}", buf.span,
                           related=(Related(partner.span, "peer buffer declared here"),))
            return None
        return partner

    def _finish(self, pairs: dict[tuple[str, str], tuple[Buffer, Buffer]]) -> list[Channel]:
        uses: dict[str, int] = {}
        for prod, cons in pairs.values():
            uses[prod.qualified] = uses.get(prod.qualified, 0) + 1
            uses[cons.qualified] = uses.get(cons.qualified, 0) + 1
        ok = True
        for shell in self.by_id.values():
            for b in shell.buffers:
                n = uses.get(b.qualified, 0)
                if n > 1:
                    ok = False
                    self.bag.error("E306", f"{b.direction.value} '{b.name}' of {shell.id} is "
                                   f"connected {n} times", b.span,
                                   "each buffer belongs to exactly one channel: name the buffer "
                                   "on the other side")
                elif n == 0 and shell.device:
                    self.bag.warn("W701", f"buffer '{b.name}' of device {shell.id} is not "
                                  "connected", shell.span)
        if not ok:
            return []
        channels: list[Channel] = []
        for i, key in enumerate(sorted(pairs)):
            prod, cons = pairs[key]
            channels.append(Channel(i + 1, replace(prod, peer=cons.owner),
                                    replace(cons, peer=prod.owner)))
        return channels


def _relative(target: Shell, viewer: Shell) -> str:
    """How `viewer` would name `target` as a peer."""
    if target.agent != viewer.agent:
        return f"{target.agent}.c"
    return "c" if target.letter == "c" else f"{target.letter}.{target.name}"
