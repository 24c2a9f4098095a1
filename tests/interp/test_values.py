"""The value representation and the checks at the boundary with Python code."""

from __future__ import annotations

import numpy as np
import pytest

from rssm_dsl.interp.values import (
    ValueTypeError,
    converter,
    default_value,
    equal,
    short,
    to_json,
)
from rssm_dsl.semantics.types import BOOL, FLOAT, INT, ArrayT, RecordT

VEC3 = ArrayT(FLOAT, 3)
POSE = RecordT("Pose", (("position", VEC3), ("ok", BOOL), ("ids", ArrayT(INT, 2))))


def test_defaults_follow_the_representation() -> None:
    v = default_value(POSE)
    assert set(v) == {"position", "ok", "ids"}
    assert isinstance(v["position"], np.ndarray) and v["position"].dtype == np.float64
    assert not v["position"].flags.writeable
    assert v["ok"] is False and v["ids"] == (0, 0)


def test_scalars_accept_widening_and_reject_bool_for_numbers() -> None:
    assert converter(FLOAT)(3) == 3.0 and isinstance(converter(FLOAT)(3), float)
    assert converter(FLOAT)(np.float32(1.5)) == 1.5
    assert converter(INT)(np.int64(4)) == 4
    with pytest.raises(ValueTypeError):
        converter(FLOAT)(True)
    with pytest.raises(ValueTypeError):
        converter(INT)(2.5)
    with pytest.raises(ValueTypeError):
        converter(BOOL)(1)


def test_float_arrays_are_copied_and_frozen() -> None:
    src = np.array([1.0, 2.0, 3.0])
    out = converter(VEC3)(src)
    assert out is not src and not out.flags.writeable
    src[0] = 9.0
    assert out[0] == 1.0
    assert list(converter(VEC3)([1, 2, 3])) == [1.0, 2.0, 3.0]
    frozen = converter(VEC3)(out)
    assert frozen is out                      # already in the representation: no copy


def test_wrong_shapes_name_the_offending_part() -> None:
    with pytest.raises(ValueTypeError) as e:
        converter(POSE)({"position": [1.0, 2.0], "ok": True, "ids": [1, 2]})
    assert "array of shape" in str(e.value) or "list of 2" in str(e.value)
    with pytest.raises(ValueTypeError) as e2:
        converter(POSE)({"position": [1.0, 2.0, 3.0], "ok": True, "ids": [1, "x"]})
    assert ".ids[1]" in str(e2.value)
    with pytest.raises(ValueTypeError) as e3:
        converter(POSE)({"position": [1.0, 2.0, 3.0], "ok": True})
    assert ".ids (missing)" in str(e3.value)
    with pytest.raises(ValueTypeError) as e4:
        converter(POSE)({"position": [0, 0, 0], "ok": True, "ids": [1, 2], "extra": 1})
    assert "extra" in str(e4.value)


def test_records_from_objects_with_attributes() -> None:
    class P:
        position = (0.0, 1.0, 2.0)
        ok = True
        ids = (3, 4)

    v = converter(POSE)(P())
    assert v["ids"] == (3, 4) and list(v["position"]) == [0.0, 1.0, 2.0]


def test_equality_json_and_text() -> None:
    a = converter(POSE)({"position": [1, 2, 3], "ok": True, "ids": [1, 2]})
    b = converter(POSE)({"position": [1.0, 2.0, 3.0], "ok": True, "ids": (1, 2)})
    c = converter(POSE)({"position": [1.0, 2.0, 4.0], "ok": True, "ids": (1, 2)})
    assert equal(a, b) and not equal(a, c)
    assert to_json(a) == {"position": [1.0, 2.0, 3.0], "ok": True, "ids": [1, 2]}
    assert to_json(float("nan")) == "nan" and to_json(float("-inf")) == "-inf"
    assert short(a).startswith("{position: [1, 2, 3]")
