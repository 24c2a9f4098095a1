"""The order in which components are composed.

The composition of the first ``k`` components keeps visible the transitions it shares with
the others; the fewer, the smaller it stays after reduction. Greedy: start with the first
part and repeatedly take, among the parts connected to what is composed (sharing a
transition with it), the one whose addition leaves the fewest open transitions (it opens
the ones it shares with parts not yet in, and closes the ones it was the last to miss);
ties go to the one sharing the most with what is composed, then to the given order. For a
ring of agents this walks round the ring, so only the channels at its two ends stay open.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence


def composition_order(alphabets: Sequence[Collection[int]]) -> list[int]:
    """An order of the parts with these alphabets, starting with part 0."""
    if not alphabets:
        return []
    users: dict[int, list[int]] = {}
    for i, alphabet in enumerate(alphabets):
        for t in alphabet:
            users.setdefault(t, []).append(i)
    remaining = {t: len(us) for t, us in users.items()}
    n = len(alphabets)
    shared = [0] * n                 # transitions of the candidate already opened
    closing = [0] * n                # transitions of which the candidate is the last user
    for us in users.values():
        if len(us) == 1:
            closing[us[0]] += 1
    opened: set[int] = set()
    done = [False] * n
    order: list[int] = []
    current = 0
    while True:
        done[current] = True
        order.append(current)
        if len(order) == n:
            return order
        for t in alphabets[current]:
            remaining[t] -= 1
            if t not in opened:
                opened.add(t)
                for j in users[t]:
                    shared[j] += 1
            if remaining[t] == 1:
                for j in users[t]:
                    if not done[j]:
                        closing[j] += 1
        current = _best(alphabets, done, shared, closing)


def _best(alphabets: Sequence[Collection[int]], done: list[bool], shared: list[int],
          closing: list[int]) -> int:
    """The next part: connected to what is composed, leaving the fewest open transitions,
    sharing the most with what is composed, first in the given order."""
    best, best_key = -1, (False, 0, 0, 0)
    for j, alphabet in enumerate(alphabets):
        if done[j]:
            continue
        grows = len(alphabet) - shared[j] - closing[j]
        key = (shared[j] > 0, -grows, shared[j], -j)
        if best < 0 or key > best_key:
            best, best_key = j, key
    return best
