"""core.points: raw -> engineering values and plausibility, with literal arrays."""

from __future__ import annotations

import numpy as np
import pytest

from gateway.core.points import (
    FLOAT32_TINY,
    OP_MARGIN,
    Implausible,
    PointSpec,
    PointTable,
    Quality,
    explain,
)
from gateway.inputs.modbus.config import ModbusPoint
from gateway.wire.codec import decode_registers, encode_values

G, U, B, N = Quality.GOOD, Quality.UNCERTAIN, Quality.BAD, Quality.NO_COMM


def _swapped(x: float) -> float:
    """``x`` written low word first, read high word first (a word-order mistake)."""
    regs = encode_values([x], "float32", "little")
    return float(decode_registers(regs, "float32", "big")[0])


def table(*ranges: tuple[float, float] | None, scale: float = 1.0,
          offset: float = 0.0) -> PointTable:
    return PointTable([PointSpec("L", "pv", i, scale, offset, r)
                       for i, r in enumerate(ranges)])


def test_scale_and_offset_are_applied_once() -> None:
    t = PointTable([PointSpec("A", "op", 0, 0.01), PointSpec("A", "pv", 1, 0.1, -50.0)])
    values, quality = t.engineering(np.array([5000.0, 700.0]), np.array([G, G], np.uint8))
    np.testing.assert_allclose(values, [50.0, 20.0])
    assert quality.tolist() == [G, G]


def test_non_finite_subnormal_and_out_of_range_are_bad() -> None:
    assert 0 < abs(_swapped(50.0)) < FLOAT32_TINY  # 50.0 word-swapped: 2.4e-41
    t = table(None, None, None, (0.0, 100.0), (0.0, 100.0), None, None)
    raw = np.array([np.nan, np.inf, _swapped(50.0), 150.0, 99.0, 0.0, -np.inf])
    values, quality = t.engineering(raw, np.full(7, G, np.uint8))
    assert quality.tolist() == [B, B, B, B, G, G, B]
    assert np.isnan(values[[0, 1, 2, 3, 6]]).all()
    assert values[4] == 99.0 and values[5] == 0.0  # zero is a value, not a subnormal


def test_a_subnormal_raw_value_is_bad_whatever_the_offset() -> None:
    values, quality = table(None, offset=-50.0).engineering(
        np.array([_swapped(50.0)]), np.array([G], np.uint8))
    assert quality.tolist() == [B] and np.isnan(values[0])


def test_the_range_is_in_engineering_units() -> None:
    t = table((0.0, 100.0), scale=0.1)
    _, quality = t.engineering(np.array([999.0, 1001.0]), np.array([G, G], np.uint8))
    assert quality.tolist() == [G, B]


def test_what_the_source_said_wins_and_is_never_a_number() -> None:
    t = table(None, None, None)
    values, quality = t.engineering(np.array([1.0, 2.0, 3.0]), np.array([U, N, B], np.uint8))
    assert quality.tolist() == [U, N, B]  # not turned into GOOD, nor BAD
    assert np.isnan(values).all()


def test_inputs_are_not_modified() -> None:
    raw, q = np.array([np.nan]), np.array([G], np.uint8)
    table(None).engineering(raw, q)
    assert q.tolist() == [G]


def test_gap_and_names() -> None:
    t = PointTable([PointSpec(f"L{i}", r, 0) for i in range(4) for r in ("op", "pv")])
    values, quality = t.gap()
    assert np.isnan(values).all() and (quality == N).all() and len(values) == 8
    assert t.names([1, 0]) == "L0.op, L0.pv"
    assert t.names(range(8), limit=3) == "L0.op, L0.pv, L1.op and 5 more"


@pytest.mark.parametrize("typ", ["int16", "uint16", "int32", "uint32"])
def test_integer_points_are_never_subnormal(typ: str) -> None:
    raw = decode_registers(encode_values([0, 1, 7], typ), typ)
    _, quality = table(None, None, None).engineering(raw, np.full(3, G, np.uint8))
    assert (quality == G).all()


# ----------------------------------------------------------- issue 23: judged, with a cause


def _op(address: object = 0, span: tuple[float, float] | None = (0.0, 100.0)) -> PointSpec:
    return PointSpec("FIC101", "op", address, span=span, origin="loops.csv: line 2")


def test_an_op_far_outside_op_range_is_implausible_a_few_percent_beyond_is_not() -> None:
    """The issue's case: an off-by-one float32 read -2.5e17 with op_range 0-100 and passed
    as GOOD; 3,000 % is a wrong register or scale; 105 % is a DCS driving OP a little
    beyond its span (OP_MARGIN)."""
    t = PointTable([_op(), _op(), _op(), _op(), _op(span=None)])
    raw = np.array([-2.5e17, 3000.0, 105.0, -9.0, 3000.0])
    values, quality, causes = t.judge(raw, np.full(5, G, np.uint8))
    assert causes.tolist() == [Implausible.HUGE, Implausible.OP_RANGE, Implausible.NONE,
                               Implausible.NONE, Implausible.NONE]
    assert quality.tolist() == [B, B, G, G, G]
    assert np.isnan(values[:2]).all()
    assert OP_MARGIN == 0.1


def test_nan_and_what_the_source_said_first() -> None:
    t = PointTable([_op(), _op()])
    _v, quality, causes = t.judge(np.array([np.nan, 5e20]), np.array([G, N], np.uint8))
    assert causes.tolist() == [Implausible.NOT_FINITE, Implausible.NONE]  # NO_COMM stays
    assert quality.tolist() == [B, N]


def test_explain_names_the_likely_cause_and_the_other_word_order() -> None:
    f32 = ModbusPoint(0, "float32")
    huge = explain(_op(f32), -2.5e17, Implausible.HUGE)
    assert huge.startswith("-2.5e+17 is beyond 1e+15: register garbage")
    assert "off by one" in huge and "word order" in huge
    swapped = _swapped(50.0)  # 50.0 with its words swapped: a subnormal
    text = explain(_op(f32), swapped, Implausible.SUBNORMAL)
    assert "word order is likely wrong" in text
    assert text.endswith("with the other word order it reads 50")
    out = explain(_op(f32), 3000.0, Implausible.OP_RANGE)
    assert out.startswith("3000 is outside op_range 0..100")
    assert "off by one" in out
    assert explain(_op(f32), 50.0, Implausible.NONE) == ""
