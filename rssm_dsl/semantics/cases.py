"""The data-availability cases of a partial transition function, defined once for the
compiler, the interpreter, the verifier and the generated ROS 2 nodes (paper Eq. 5;
docs/language.md, "Data-availability cases").

The rule. A partial function is split by ``new(x)`` of the inputs that its behaviour's case
clauses read: the *split* inputs of a behaviour are the input buffers named in ``new(x)`` by
any ``case`` clause of any of its partial functions. A partial function with case clauses
has one case per combination of new(x) of those split inputs, 2^k of them for k split inputs;
a partial function without case clauses (a plain `update`, or none) has one case. Inputs
that no case clause of the behaviour reads split nothing: a case stands for every
combination of them. So a subsystem with 64 inputs and no `case` has one case per partial
function, and the paper's LWR4+ (whose cases read both of its two inputs) keeps the paper's
four cases per partial function (Fig. 16).

Beyond FULL_SPLIT split inputs (2^k would be too many cases: a user whose clauses read 20
inputs), a partial function has the cases its clauses decide instead: new(x) is decided
input by input (in declaration order) only as long as some clause's value still depends on
it, so each case is a *cube*: the combination of the inputs decided on its way, the others
``None``; each stands for one clause (or `otherwise`) for every value of the inputs it leaves
open. A clause that is a conjunction of k literals gives about k + 1 cases, not 2^k. Such a
function's cases fix different inputs; the backends read a case as "new(x) of the inputs it
fixes equal its combination" (:func:`covers`), which holds for both forms.

A case's combination is written per input of the subsystem: ``True`` (new), ``False`` (not
new), ``None`` (not split: any). In the paper's form cases are numbered as Eq. 5 numbers
them, over the split inputs: varpi = 1 is "all new", the first split input varies fastest;
cubes are numbered in the order of the decision (new before not new). At run time new(x) of
all the inputs is a bit mask (bit k: input k, rssm_core.iteration.NewFlags); the case it
selects is the one whose combination :func:`covers` it (in the paper's form, the case numbered
:func:`case_number` of the mask).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

Combination = tuple[bool | None, ...]       # new(x) per input; None: not split by the case
FULL_SPLIT = 8         # the paper's 2^k cases up to k split inputs; beyond, cubes (above)


def split_of(new: Combination) -> tuple[int, ...]:
    """The inputs a case's combination fixes (the split inputs of its partial function)."""
    return tuple(k for k, v in enumerate(new) if v is not None)


def combinations(split: Sequence[int], n: int) -> list[Combination]:
    """The 2^k combinations over the ``split`` inputs (k of them) of a subsystem with ``n``
    inputs, in the order of their numbers varpi = 1, 2, ... (Eq. 5: varpi = 1 all new, the
    first split input varying fastest); the other inputs are ``None``."""
    out: list[Combination] = []
    for v in range(1 << len(split)):
        new: list[bool | None] = [None] * n
        for i, k in enumerate(split):
            new[k] = not v >> i & 1
        out.append(tuple(new))
    return out


def number_of(new: Combination) -> int:
    """varpi of a combination: 1 + the split inputs that are not new, as bits (the first
    split input is bit 0)."""
    return 1 + sum(1 << i for i, v in enumerate(x for x in new if x is not None) if not v)


def case_number(mask: int, split: Sequence[int]) -> int:
    """varpi of the case that the run-time new(x) ``mask`` (bit k: input k) selects."""
    return 1 + sum(1 << i for i, k in enumerate(split) if not mask >> k & 1)


def bits(mask: int, split: Sequence[int]) -> int:
    """The run-time new(x) ``mask`` restricted to the ``split`` inputs: bit i is new(x) of
    input ``split[i]`` (the row of the case in a table ordered by mask, as the generated
    ROS 2 nodes order theirs)."""
    return sum((mask >> k & 1) << i for i, k in enumerate(split))


def uniform(cases: Sequence[Combination]) -> bool:
    """The cases are the 2^k combinations of one set of k split inputs (the paper's form),
    so a table indexed by their new(x) bits selects them."""
    split = split_of(cases[0]) if cases else ()
    return len(cases) == 1 << len(split) and all(split_of(c) == split for c in cases)


def care_want(new: Combination) -> tuple[int, int]:
    """A case as two bit masks: the inputs it fixes, and those of them it wants new; the
    run-time ``mask`` selects it when ``mask & care == want``."""
    care = sum(1 << k for k, v in enumerate(new) if v is not None)
    return care, sum(1 << k for k, v in enumerate(new) if v)


def selector(split: Sequence[int]) -> Callable[[int], int]:
    """``mask -> varpi - 1``: the row of the case in a table ordered by varpi (fast forms
    for no split input and for the inputs 0..k-1)."""
    ks = tuple(split)
    if not ks:
        return lambda mask: 0
    if ks == tuple(range(len(ks))):
        full = (1 << len(ks)) - 1
        return lambda mask: ~mask & full
    return lambda mask: case_number(mask, ks) - 1


def covers(new: Combination, values: Sequence[bool | None]) -> bool:
    """The case of combination ``new`` stands for the full combination ``values`` (new(x)
    of every input)."""
    return all(v is None or v == values[k] for k, v in enumerate(new))


def text(inputs: Sequence[str], new: Iterable[bool | None]) -> str:
    """A combination in the DSL's words: ``new(a) and not new(b)``; inputs not split are
    left out (``any data`` when none is split)."""
    words = [f"new({x})" if v else f"not new({x})"
             for x, v in zip(inputs, new, strict=True) if v is not None]
    return " and ".join(words) if words else "any data" if inputs else "(no inputs)"
