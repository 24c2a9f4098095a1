"""The token game of the flat net: markings, enabled transitions, firing.

A transition is *enabled* when each of its input places holds a *usable* token. A place's
token is usable once the operation of the place has finished (paper V-C): :meth:`occupy`
puts a token that is not usable yet, :meth:`release` makes it usable. The enabled set is
kept up to date incrementally: each transition counts its input places without a usable
token, so a firing touches only the transitions that share a place with it.

The rule is :mod:`rssm_core.firing`'s; this is its incremental fast path, with the structure
(pre-sets, post-sets, consumers) taken from the :class:`~rssm_core.firing.Net` of the flat net
(``game.rule``), and ``tests/core`` proves it equal to the rule on random nets. A firing that
would put a second token into a place is an :class:`UnsafeFiring` (E807) raised at the first
such output place.
"""

from __future__ import annotations

import random

from rssm_core.firing import Net, UnsafeFiring
from rssm_dsl.hpn.flat import FlatNet

__all__ = ["TokenGame", "UnsafeFiring"]


class TokenGame:
    __slots__ = ("consumers", "enabled", "missing", "net", "post", "pre", "rule", "tokens",
                 "usable")

    def __init__(self, net: FlatNet, rule: Net | None = None) -> None:
        self.net = net
        self.rule = rule if rule is not None else net.rule
        self.pre: list[tuple[int, ...]] = list(self.rule.pre)
        self.post: list[tuple[int, ...]] = list(self.rule.post)
        self.consumers: list[tuple[int, ...]] = list(self.rule.consumers)
        self.missing: list[int] = [len(ps) for ps in self.pre]
        # lists rather than bytearrays: the compiled firing code indexes them with constants,
        # which Python specialises for lists only
        self.tokens: list[int] = [0] * len(net.places)   # a token is there (usable or not)
        self.usable: list[int] = [0] * len(net.places)   # ... and its operation has finished
        self.enabled: set[int] = set(self.rule.sources)
        for p in sorted(net.initial):
            self.tokens[p] = 1
            self.release(p)

    # ------------------------------------------------------------------ primitives
    def release(self, p: int) -> None:
        """The token in ``p`` becomes usable."""
        self.usable[p] = 1
        missing, enabled = self.missing, self.enabled
        for t in self.consumers[p]:
            m = missing[t] - 1
            missing[t] = m
            if m == 0:
                enabled.add(t)

    def consume(self, t: int) -> None:
        """Remove the tokens of ``t``'s input places."""
        missing, enabled, consumers = self.missing, self.enabled, self.consumers
        tokens, usable = self.tokens, self.usable
        for p in self.pre[t]:
            tokens[p] = 0
            usable[p] = 0
            for u in consumers[p]:
                if missing[u] == 0:
                    enabled.discard(u)
                missing[u] += 1

    def occupy(self, t: int, p: int) -> None:
        """Put a (not yet usable) token into ``p``, an output place of ``t``."""
        if self.tokens[p]:
            raise UnsafeFiring(t, p)
        self.tokens[p] = 1

    def fire(self, t: int) -> None:
        """Fire ``t`` with every output token usable at once (no operations)."""
        self.consume(t)
        for p in self.post[t]:
            self.occupy(t, p)
            self.release(p)

    def recompute_enabled(self) -> None:
        """Make the enabled set complete again (the deterministic loop keeps local steps
        out of it while it runs)."""
        self.enabled.clear()
        self.enabled.update(t for t, m in enumerate(self.missing) if m == 0)

    # ------------------------------------------------------------------ views
    def marking(self) -> frozenset[int]:
        return frozenset(i for i, v in enumerate(self.tokens) if v)

    def marked_names(self) -> list[str]:
        return [self.net.places[i].name for i, v in enumerate(self.tokens) if v]

    # ------------------------------------------------------------------ the pure token game
    def run_free(self, steps: int, seed: int = 0) -> int:
        """Fire up to ``steps`` transitions chosen uniformly among the enabled ones (data
        conditions as free choices, no operations, no time): the verifier's abstraction.
        Returns the number of firings (fewer when a dead marking is reached)."""
        rnd = random.Random(seed).random
        pre, post, consumers = self.pre, self.post, self.consumers
        missing, enabled, tokens, usable = self.missing, self.enabled, self.tokens, self.usable
        fired = 0
        while fired < steps:
            if not enabled:
                break
            candidates = list(enabled)
            t = candidates[int(rnd() * len(candidates))]
            for p in pre[t]:
                tokens[p] = 0
                usable[p] = 0
                for u in consumers[p]:
                    if missing[u] == 0:
                        enabled.discard(u)
                    missing[u] += 1
            for p in post[t]:
                if tokens[p]:
                    raise UnsafeFiring(t, p)
                tokens[p] = 1
                usable[p] = 1
                for u in consumers[p]:
                    m = missing[u] - 1
                    missing[u] = m
                    if m == 0:
                        enabled.add(u)
            fired += 1
        return fired
