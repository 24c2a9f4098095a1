"""The finite types in the value domain: `finite_domain` (what the verifier enumerates), the
descriptors, defaults and converters of enums and ranges (rssm_core.values), and the range
check on store (E802)."""

from __future__ import annotations

import numpy as np
import pytest

import rssm_core.values as rt
from rssm_dsl.semantics.types import (
    BOOL,
    FLOAT,
    INT,
    ArrayT,
    EnumT,
    RangeT,
    RecordT,
    assignable,
    descriptor,
    finite_domain,
    join,
)

PHASE = EnumT("Phase", ("idle", "approach", "grasp"))


def test_finite_domain() -> None:
    assert finite_domain(BOOL) == (False, True)
    assert finite_domain(PHASE) == ("idle", "approach", "grasp")
    assert finite_domain(RangeT(0, 3)) == (0, 1, 2, 3)
    assert finite_domain(RangeT(-2, 1)) == (-2, -1, 0, 1)
    assert finite_domain(RangeT(5, 5)) == (5,)
    assert finite_domain(RangeT(0, 63)) == tuple(range(64))          # 64 values: enumerated
    assert finite_domain(RangeT(0, 64)) is None                       # 65: too many
    for t in (INT, FLOAT, ArrayT(BOOL, 2), ArrayT(PHASE, 2), RecordT("R", (("p", PHASE),))):
        assert finite_domain(t) is None, t


def test_types_print_and_describe() -> None:
    assert str(PHASE) == "Phase" and str(RangeT(-5, 5)) == "-5..5"
    assert descriptor(PHASE) == ("enum", "Phase", ("idle", "approach", "grasp"))
    assert descriptor(RangeT(0, 3)) == ("range", 0, 3)
    assert descriptor(ArrayT(RangeT(0, 3), 2)) == ("array", ("range", 0, 3), 2)
    assert rt.type_text(descriptor(PHASE)) == "Phase"
    assert rt.type_text(descriptor(ArrayT(RangeT(0, 3), 2))) == "0..3[2]"


def test_a_range_is_a_subtype_of_int() -> None:
    r = RangeT(0, 3)
    assert assignable(r, INT) and assignable(INT, r) and assignable(r, FLOAT)
    assert assignable(RangeT(0, 9), r) and assignable(ArrayT(INT, 2), ArrayT(r, 2))
    assert not assignable(FLOAT, r) and not assignable(BOOL, r)
    assert join(r, r) == r and join(r, RangeT(0, 9)) == INT and join(r, FLOAT) == FLOAT
    assert not assignable(PHASE, INT) and not assignable(INT, PHASE)
    assert not assignable(EnumT("Other", PHASE.members), PHASE)
    assert join(PHASE, INT) is None


def test_defaults() -> None:
    assert rt.default(descriptor(PHASE)) == "idle"                    # the first member
    assert rt.default(("range", 0, 3)) == 0
    assert rt.default(("range", 2, 9)) == 2                           # the bound nearest 0
    assert rt.default(("range", -9, -2)) == -2
    assert rt.default(("array", ("range", 1, 3), 2)) == (1, 1)


def test_converters_at_the_python_boundary() -> None:
    to_phase = rt.converter(descriptor(PHASE))
    assert to_phase("grasp") == "grasp"
    for bad in ("Grasp", "nothing", 1, None):
        with pytest.raises(rt.ValueTypeError):
            to_phase(bad)
    to_range = rt.converter(("range", 0, 3))
    assert to_range(3) == 3 and type(to_range(np.int64(2))) is int
    for bad in (4, -1, 2.0, True, "2"):
        with pytest.raises(rt.ValueTypeError):
            to_range(bad)
    rec = rt.converter(descriptor(RecordT("Grip", (("phase", PHASE), ("n", RangeT(0, 3))))))
    assert rec({"phase": "idle", "n": 1}) == {"phase": "idle", "n": 1}
    with pytest.raises(rt.ValueTypeError, match=r"\.n"):
        rec({"phase": "idle", "n": 7})


def test_a_value_stored_outside_its_range_fails() -> None:
    assert rt.in_range(3, 0, 3, "retries", "here") == 3
    with pytest.raises(rt.OperationError) as e:
        rt.in_range(4, 0, 3, "retries", "spec.rssm:3:5")
    assert e.value.code == "E802" and e.value.message == "value 4 is outside 0..3 of retries"
    desc = ("array", ("range", 0, 3), 2)
    assert rt.check_ranges((0, 3), desc, "slots", "here") == (0, 3)
    with pytest.raises(rt.OperationError, match=r"value 9 is outside 0\.\.3 of slots\[1\]"):
        rt.check_ranges((0, 9), desc, "slots", "here")


def test_enum_values_are_names_in_json_and_text() -> None:
    assert rt.to_json({"phase": "grasp", "n": 2}) == {"phase": "grasp", "n": 2}
    assert rt.short(("idle", "grasp")) == "[idle, grasp]"
    assert rt.equal("grasp", "grasp") and not rt.equal("grasp", "idle")
