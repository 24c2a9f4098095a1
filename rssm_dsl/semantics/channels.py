"""Pair buffers into channels and check the links the methodology allows (paper III-A).

A buffer of a designed subsystem names its peer relative to its agent: `c`, `e.NAME`,
`r.NAME`, `E.NAME`, `R.NAME`, or `AGENT.c` for another agent's control subsystem; a
trailing `.BUFFER` picks one buffer of the peer. Without it, a buffer pairs with the peer's
buffer of the opposite direction that names it back (devices always do) and is not taken by
another buffer (by `.BUFFER` or by having its name); when several remain, the one with the
same name wins.
Allowed links: c-e, c-r, e-E, r-R inside an agent, and c-c between agents (T buffers).
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import replace

from rssm_dsl.diagnostics import DiagnosticBag, Related
from rssm_dsl.semantics.model import Buffer, Channel
from rssm_dsl.semantics.structure import AgentShell, Shell
from rssm_dsl.semantics.typecheck import did_you_mean
from rssm_dsl.syntax import ast

_ALLOWED = {frozenset("ce"), frozenset("cr"), frozenset("eE"), frozenset("rR")}
_LETTERS = {"c", "e", "r", "E", "R"}
_TALKS_TO = {
    "c": "a control subsystem talks to its agent's virtual effectors and receptors and to "
         "other agents' control subsystems",
    "e": "a virtual effector talks to its agent's control subsystem and real effectors",
    "r": "a virtual receptor talks to its agent's control subsystem and real receptors",
}


def _link_allowed(a: Shell, b: Shell) -> bool:
    if a.agent != b.agent:
        return a.letter == "c" and b.letter == "c"
    return frozenset((a.letter, b.letter)) in _ALLOWED


class ChannelPass:
    def __init__(self, bag: DiagnosticBag, agents: list[AgentShell],
                 failed: Collection[str] = ()) -> None:
        self.bag = bag
        self.agents = {a.name: a for a in agents}
        self.failed_agents = frozenset(failed)   # of instance lines reported (instances.py)
        self.by_id = {s.id: s for a in agents for s in a.shells}
        self.broken = set().union(*(a.broken for a in agents))  # device instances reported
        self.failed: set[str] = set()   # shells at the far end of a link already reported
        self.mismatched: set[frozenset[str]] = set()  # buffer pairs with an E305 reported

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
        if letter in self.failed_agents and len(parts) >= 2:
            return None
        if letter not in _LETTERS and parts[1:2] == ["c"]:
            guess = did_you_mean(letter, self.agents)
            bag.error("E303", f"'{peer}': there is no agent '{letter}'", peer.span,
                      f"did you mean '{guess}.c'?" if guess else
                      "agents: " + ", ".join(sorted(self.agents)))
            return None
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
        if target is None and target_id in self.broken:
            return None  # its declaration is already reported
        if target is None:
            prefix = target_id.rsplit(".", 1)[0] + "."
            guess = did_you_mean(target_id, [i for i in self.by_id if i.startswith(prefix)])
            bag.error("E303", f"{target_id} does not exist", peer.span,
                      f"did you mean {guess.removeprefix(f'{owner.agent}.')}?" if guess
                      else f"declare it in agent '{agent}'")
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
                        "E302", f"{shell.id} cannot be linked to {peer.id}: "
                        f"{_TALKS_TO[shell.letter]}", ref.span,
                        "allowed links: c-e, c-r, e-E, r-R inside an agent, c-c between agents",
                    )
                    self.failed.add(peer.id)
                    continue
                partner = self._partner(shell, buf, peer, wanted, ref)
                if partner is None:
                    self.failed.add(peer.id)
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
                          and self._points_back(b, peer, shell, buf)
                          and not self._claimed(b, peer, shell, buf)]
            if len(candidates) > 1:
                same = [b for b in candidates if b.name == buf.name]
                candidates = same or candidates
        if not candidates and self._unsure(peer, opposite):
            return None  # the peer's own buffer is broken and reported there
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
            # the example offered is one of the buffer's own type when there is one
            fits = [b for b in candidates if b.type == buf.type]
            self.bag.error("E306", f"several buffers of {peer.id} could match '{buf.name}': "
                           f"{names}", ref.span, f"write `{ref}.BUFFER`, e.g. `{ref}."
                           f"{(fits or candidates)[0].name}`" + (
                               f" (of type {buf.type}, as '{buf.name}' is)" if fits else
                               f"; none of them is of type {buf.type}, as '{buf.name}' is"))
            return None
        partner = candidates[0]
        if partner.type != buf.type:
            pair = frozenset((buf.qualified, partner.qualified))
            if pair not in self.mismatched:  # once per channel, seen from the first side
                self.mismatched.add(pair)
                self.bag.error("E305", f"'{buf.name}' is {buf.type} but its peer buffer "
                               f"{partner.qualified} is {partner.type}", buf.span,
                               related=(Related(partner.span, "peer buffer declared here"),))
            return None
        return partner

    def _claimed(self, candidate: Buffer, holder: Shell, owner: Shell, owner_buf: Buffer
                 ) -> bool:
        """Is `candidate` (a buffer of `holder`) taken by another buffer of `owner`, one that
        names it (`PEER.BUFFER`) or has its name?"""
        for other in owner.buffers:
            if other is owner_buf or other.direction is not owner_buf.direction:
                continue
            ref = owner.peers.get(other.name)
            resolved = self._resolve(owner, ref, report=False) if ref is not None else None
            if resolved is None or resolved[0] is not holder:
                continue
            if resolved[1] == candidate.name or (resolved[1] is None
                                                 and other.name == candidate.name):
                return True
        return False

    def _unsure(self, shell: Shell, direction: ast.Direction) -> bool:
        """Has `shell` a buffer of this direction that could not be paired because its own
        declaration is broken (unknown type, missing or unresolvable peer)?"""
        if any(isinstance(d, ast.BufferDecl) and d.direction is direction
               for d in shell.unresolved):
            return True
        if shell.device:
            return False
        for b in shell.buffers:
            ref = shell.peers.get(b.name)
            if b.direction is direction and (
                    ref is None or self._resolve(shell, ref, report=False) is None):
                return True
        return False

    def _doubtful(self) -> set[str]:
        """Shells whose missing links may be echoes of errors reported elsewhere: the far ends
        of rejected links and the peers named by buffers of unknown type."""
        out = set(self.failed)
        for shell in self.by_id.values():
            for d in shell.unresolved:
                if isinstance(d, ast.BufferDecl) and d.peer is not None:
                    resolved = self._resolve(shell, d.peer, report=False)
                    if resolved is not None:
                        out.add(resolved[0].id)
        return out

    def _finish(self, pairs: dict[tuple[str, str], tuple[Buffer, Buffer]]) -> list[Channel]:
        uses: dict[str, int] = {}
        for prod, cons in pairs.values():
            uses[prod.qualified] = uses.get(prod.qualified, 0) + 1
            uses[cons.qualified] = uses.get(cons.qualified, 0) + 1
        ok = True
        doubtful = self._doubtful()
        for shell in self.by_id.values():
            for b in shell.buffers:
                n = uses.get(b.qualified, 0)
                if n > 1:
                    ok = False
                    self.bag.error("E306", f"{b.direction.value} '{b.name}' of {shell.id} is "
                                   f"connected {n} times", b.span,
                                   "each buffer belongs to exactly one channel: name the buffer "
                                   "on the other side")
                elif n == 0 and shell.device and shell.id not in doubtful:
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
