"""Pair buffers into channels and check the links the methodology allows (paper III-A).

A buffer of a designed subsystem names its peer relative to its agent: `c`, `e.NAME`,
`r.NAME`, `E.NAME`, `R.NAME`, or `AGENT.c` for another agent's control subsystem; a
trailing `.BUFFER` picks one buffer of the peer. Without it, a buffer pairs with the peer's
buffer of the opposite direction that names it back (devices always do) and is not taken by
another buffer (by `.BUFFER` or by having its name); when several remain, the one with the
same name wins.
Allowed links: c-e, c-r, e-E, r-R inside an agent, and c-c between agents (T buffers).

Linear in the buffers: each buffer's peer is resolved once (`_resolved`), and the buffers
that name a peer, or that are taken by name, are indexed per pair of subsystems (`_claims`,
`_pointing`), so pairing a buffer does not scan its peer's buffers (3,000 buffers between
two subsystems took minutes: every candidate was checked against every buffer).
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import replace

from rssm_core.records import dataclass
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

SHOWN_CANDIDATES = 4     # E306 names this many of the buffers that could match


@dataclass(frozen=True)
class _Pointing:
    """The buffers of one subsystem (of one direction) that name one other subsystem as
    their peer, with their positions among its buffers (ChannelPass._pointing)."""

    any_buffer: list[tuple[int, Buffer]]                   # naming none of its buffers
    any_by_name: dict[str, tuple[int, Buffer]]             # the same, by their names
    naming: dict[str, list[tuple[int, Buffer]]]            # naming one, by that one's name


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
        # the indexes (built when first needed; see the module's docstring)
        self._silent: dict[tuple[str, str], tuple[Shell, str | None] | None] = {}
        self._claims_by: dict[str, dict[tuple[str, ast.Direction], dict[str, list[str]]]] = {}
        self._pointing_by: dict[str, dict[tuple[str, ast.Direction], _Pointing]] = {}
        self._unclaimed: dict[tuple[str, str, ast.Direction], list[tuple[int, Buffer]]] = {}
        self._by_name: dict[str, dict[str, Buffer]] = {}
        self._unsure_memo: dict[tuple[str, ast.Direction], bool] = {}

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
            if not report:
                return None
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
        if target is None and not report:
            return None
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

    def _resolved(self, shell: Shell, name: str) -> tuple[Shell, str | None] | None:
        """The peer of buffer ``name`` of ``shell`` (and the peer's buffer it names), resolved
        once without reporting; None when it has none or it does not resolve."""
        key = (shell.id, name)
        if key not in self._silent:
            ref = shell.peers.get(name)
            self._silent[key] = (self._resolve(shell, ref, report=False)
                                 if ref is not None else None)
        return self._silent[key]

    def _claims(self, owner: Shell) -> dict[tuple[str, ast.Direction], dict[str, list[str]]]:
        """Per (peer id, direction), the buffers of ``owner`` of that direction that take
        each buffer of the peer: by naming it (`PEER.BUFFER`) or by having its name."""
        out = self._claims_by.get(owner.id)
        if out is None:
            out = {}
            for other in owner.buffers:
                resolved = self._resolved(owner, other.name)
                if resolved is None:
                    continue
                holder, wanted = resolved
                taken = wanted if wanted is not None else other.name
                out.setdefault((holder.id, other.direction), {}).setdefault(
                    taken, []).append(other.name)
            self._claims_by[owner.id] = out
        return out

    def _pointing(self, holder: Shell) -> dict[tuple[str, ast.Direction], _Pointing]:
        """Per (subsystem id, direction), the buffers of ``holder`` of that direction that
        name the subsystem as their peer: those naming none of its buffers (in
        declaration order, with their positions) and those naming one, by its name. A
        device's buffers name every peer (an empty id)."""
        out = self._pointing_by.get(holder.id)
        if out is None:
            out = {}
            for i, b in enumerate(holder.buffers):
                if holder.device:
                    target, wanted = "", None
                else:
                    resolved = self._resolved(holder, b.name)
                    if resolved is None:
                        continue
                    target, wanted = resolved[0].id, resolved[1]
                entry = out.setdefault((target, b.direction), _Pointing([], {}, {}))
                if wanted is None:
                    entry.any_buffer.append((i, b))
                    entry.any_by_name[b.name] = (i, b)
                else:
                    entry.naming.setdefault(wanted, []).append((i, b))
            self._pointing_by[holder.id] = out
        return out

    def _buffer_named(self, shell: Shell, name: str) -> Buffer | None:
        names = self._by_name.get(shell.id)
        if names is None:
            names = self._by_name[shell.id] = {}
            for b in shell.buffers:
                names.setdefault(b.name, b)
        return names.get(name)

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

    def _candidates(self, shell: Shell, buf: Buffer, peer: Shell, opposite: ast.Direction
                    ) -> list[Buffer]:
        """The buffers of ``peer`` that ``buf`` (naming no buffer of it) may pair with: of
        the opposite direction, naming ``shell`` back (with no buffer or with ``buf``) and
        not taken by another buffer of ``shell``; the one with ``buf``'s name alone when it
        is one of them (it wins). In ``peer``'s declaration order."""
        claims = self._claims(shell).get((peer.id, buf.direction), {})
        pointing = self._pointing(peer).get(("" if peer.device else shell.id, opposite))
        if pointing is None:
            return []

        def free(b: Buffer) -> bool:
            return all(n == buf.name for n in claims.get(b.name, ()))

        same = pointing.any_by_name.get(buf.name)
        if same is not None and free(same[1]):
            return [same[1]]
        found = [x for x in pointing.naming.get(buf.name, ()) if free(x[1])]
        if any(b.name == buf.name for _, b in found):
            return [b for _, b in found if b.name == buf.name]
        key = (shell.id, peer.id, buf.direction)
        unclaimed = self._unclaimed.get(key)
        if unclaimed is None:   # those naming no buffer that no buffer of shell takes
            unclaimed = self._unclaimed[key] = [x for x in pointing.any_buffer
                                                if not claims.get(x[1].name)]
        if not found:
            return [b for _, b in unclaimed]
        merged = dict(unclaimed) | dict(found)      # by position
        return [merged[i] for i in sorted(merged)]

    def _partner(self, shell: Shell, buf: Buffer, peer: Shell, wanted: str | None,
                 ref: ast.PeerRef) -> Buffer | None:
        opposite = (ast.Direction.INPUT if buf.direction is ast.Direction.OUTPUT
                    else ast.Direction.OUTPUT)
        if wanted is not None:
            found = self._buffer_named(peer, wanted)
            if found is None or found.direction is not opposite:
                self.bag.error("E304", f"{peer.id} has no {opposite.value} buffer '{wanted}'",
                               ref.span)
                return None
            candidates = [found]
        else:
            candidates = self._candidates(shell, buf, peer, opposite)
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
            names = ", ".join(b.name for b in candidates[:SHOWN_CANDIDATES]) + (
                f" and {len(candidates) - SHOWN_CANDIDATES} more"
                if len(candidates) > SHOWN_CANDIDATES else "")
            self.bag.error("E306", f"several buffers of {peer.id} could match '{buf.name}': "
                           f"{names}", ref.span, _which(ref, buf, candidates, peer))
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

    def _unsure(self, shell: Shell, direction: ast.Direction) -> bool:
        """Has `shell` a buffer of this direction that could not be paired because its own
        declaration is broken (unknown type, missing or unresolvable peer)?"""
        key = (shell.id, direction)
        if key not in self._unsure_memo:
            self._unsure_memo[key] = (
                any(isinstance(d, ast.BufferDecl) and d.direction is direction
                    for d in shell.unresolved)
                or (not shell.device and any(
                    b.direction is direction and self._resolved(shell, b.name) is None
                    for b in shell.buffers)))
        return self._unsure_memo[key]

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


HINTED_AT_MOST = 5    # buffers an E306 hint offers (the message lists every candidate)


def _which(ref: ast.PeerRef, buf: Buffer, candidates: list[Buffer], peer: Shell) -> str:
    """E306's hint: the candidates that could be written after ``ref``, those of the
    buffer's own type only (a channel joins two buffers of one type: another would be
    E305); none when none is."""
    fits = [b for b in candidates if b.type == buf.type]
    same = f"of type {buf.type}, as '{buf.name}' is"
    if not fits:
        return (f"none of them is {same}: declare one in {peer.id}, or give '{buf.name}' "
                "the type of the buffer it is meant to pair with, and name that buffer: "
                f"`{ref}.BUFFER`")
    if len(fits) == 1:
        return f"write `{ref}.{fits[0].name}`: of them, only '{fits[0].name}' is {same}"
    shown = ", ".join(f"`{ref}.{b.name}`" for b in fits[:HINTED_AT_MOST])
    more = len(fits) - HINTED_AT_MOST
    return (f"write `{ref}.BUFFER` with one {same}: {shown}"
            + (f" (and {more} more)" if more > 0 else ""))


def _relative(target: Shell, viewer: Shell) -> str:
    """How `viewer` would name `target` as a peer."""
    if target.agent != viewer.agent:
        return f"{target.agent}.c"
    return "c" if target.letter == "c" else f"{target.letter}.{target.name}"
