"""wire.results: the result-register map, in one place (docs/modbus-map.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from prometheus_client import CollectorRegistry
from result_fixtures import NO_KP, sample_store

from gateway.core.store import ResultStore
from gateway.outputs.prometheus import StoreCollector
from gateway.wire.results import (
    LAYOUT,
    RESULT_BLOCK_SIZE,
    VERDICT_CODES,
    decode_block,
    overlapping_blocks,
    result_block,
    unit_images,
    verdict_code,
)
from stiction import Assessment, Verdict


def _decode_block(regs: np.ndarray, word_order: str = "big") -> dict[str, float]:
    b = decode_block(regs, word_order)
    return {"code": b["code"], "seq": b["seq"], "si": b["stiction_index"],
            "fd": b["fd_percent"], "fs": b["fs_percent"], "period": b["period_s"],
            "jump": b["jump_percent"], "t": b["timestamp"], "fill": b["window_fill"],
            "confidence": b["confidence"], "reserved": b["reserved"]}


@pytest.mark.parametrize("word_order", ["big", "little"])
def test_result_block_layout(word_order: str) -> None:
    st = sample_store(latest=False)
    b = _decode_block(result_block(st.results[0], code=verdict_code(st.results[0]),
                                   word_order=word_order), word_order)
    assert b["code"] == 4
    assert b["seq"] == 2
    assert b["si"] == pytest.approx(0.93)
    assert b["fd"] == pytest.approx(27.0)
    assert b["fs"] == pytest.approx(30.0)
    assert b["period"] == pytest.approx(228.0)
    assert b["jump"] == pytest.approx(3.0)
    assert b["t"] == 1_700_000_300
    assert b["fill"] == pytest.approx(0.5)
    assert b["confidence"] == pytest.approx(0.91)
    assert b["reserved"] == 0
    b = _decode_block(result_block(st.results[1], code=verdict_code(st.results[1]),
                                   word_order=word_order), word_order)
    assert (b["code"], b["seq"]) == (2, 1)
    assert math.isnan(b["fs"])
    assert math.isnan(b["fd"])
    assert math.isnan(b["confidence"])  # assessed before confidence existed
    none = _decode_block(result_block(None, code=0, word_order=word_order), word_order)
    assert (none["code"], none["seq"], none["t"], none["reserved"]) == (0, 0, 0, 0)
    for key in ("si", "fd", "fs", "period", "jump", "fill", "confidence"):
        assert math.isnan(none[key]), key  # never assessed: NaN, never 0.0
    st.set_stale(np.array([0]), True)
    assert verdict_code(st.results[0], bool(st.stale[0])) == 6


def test_the_layout_fits_the_block_and_the_codes_are_the_documented_ones() -> None:
    # a byte of a register counts as half of it: (register, byte) pairs never overlap
    used = [(r, half) for f in LAYOUT for r in range(f.offset, f.offset + f.width)
            for half in ((f.byte,) if f.byte else ("high", "low"))]
    assert len(used) == len(set(used)) and max(r for r, _ in used) < RESULT_BLOCK_SIZE == 20
    assert [(f.name, f.offset, f.type) for f in LAYOUT][:2] == [("code", 0, "uint16"),
                                                              ("seq", 1, "uint16")]
    assert VERDICT_CODES == {"none": 0, "not_oscillating": 1, "no_stiction": 2,
                             "undetermined": 3, "stiction": 4, "bad_data": 5, "stale": 6,
                             "valve_not_responding": 7, "warming_up": 8, "device_down": 9,
                             "propagated": 10}
    st = sample_store(latest=False)
    assert [verdict_code(r) for r in st.results] == [4, 2, 0]
    assert verdict_code(st.results[0], stale=True) == 6


# the addresses every field had before issue 21: they never move
BEFORE_ISSUE_21 = {"code": (0, "uint16"), "seq": (1, "uint16"),
                   "stiction_index": (2, "float32"), "fd_percent": (4, "float32"),
                   "fs_percent": (6, "float32"), "period_s": (8, "float32"),
                   "jump_percent": (10, "float32"), "timestamp": (12, "uint32"),
                   "window_fill": (14, "float32"), "confidence": (16, "float32")}


def test_the_plant_registers_are_new_addresses_and_read_back() -> None:
    fields = {f.name: (f.offset, f.type) for f in LAYOUT}
    assert {k: fields[k] for k in BEFORE_ISSUE_21} == BEFORE_ISSUE_21
    plant = {f.name: (f.offset, f.type, f.byte) for f in LAYOUT if f.name.startswith("plant")}
    assert plant == {"plant_role": (18, "uint8", "high"), "plant_group": (18, "uint8", "low"),
                     "plant_source": (19, "uint16", "")}
    st = sample_store(latest=False)
    for word_order in ("big", "little"):
        regs = result_block(st.results[0], code=4, word_order=word_order, plant=(3, 2, 417))
        assert regs[18] == 2 * 256 + 3 and regs[19] == 417
        b = decode_block(regs, word_order)
        assert (b["plant_group"], b["plant_role"], b["plant_source"]) == (3, 2, 417)
        assert b["fd_percent"] == pytest.approx(27.0) and b["reserved"] == 0
    none = decode_block(result_block(None, code=0))
    assert (none["plant_group"], none["plant_role"], none["plant_source"]) == (0, 0, 0)


def test_sequence_numbers_wrap_and_negative_times_read_zero() -> None:
    st = ResultStore(["A"])
    for _ in range(3):
        st.set_result(0, NO_KP, t=-5.0, window_fill=0.0, samples=0)
    res = st.results[0]
    assert res is not None
    wrapped = type(res)(res.assessment, 65537, res.t, res.window_fill, res.samples)
    b = decode_block(result_block(wrapped, code=2))
    assert b["seq"] == 1 and b["timestamp"] == 0
    assert math.isnan(b["fd_percent"])


def test_overlapping_blocks_within_a_unit_id_only() -> None:
    blocks = [("A", 1, 0), ("B", 1, 10), ("C", 2, 0), ("D", 2, 20), ("E", 1, 40), ("F", 1, 59)]
    assert list(overlapping_blocks(blocks)) == [("B", 1, 10, "A", 0), ("F", 1, 59, "E", 40)]
    assert list(overlapping_blocks([("A", 1, 0), ("B", 1, 20)])) == []


def test_unit_images_hold_every_block() -> None:
    images = unit_images({1: [0, 100], 2: []})
    assert len(images[1]) == 120 and len(images[2]) == RESULT_BLOCK_SIZE
    assert not images[1].any()


def test_a_fitted_valve_size_fills_the_jump_in_registers_and_metrics() -> None:
    """Issue 23 item 7: fd and fs from the valve fitted to PV (no jump of its own): the
    jump register and series hold J = K (fs - fd) in the one unit, not NaN / nothing."""
    st = ResultStore(["FIC101"])
    st.set_result(0, Assessment(Verdict.STICTION, "test", fd=0.20, fs=0.25, fd_op=20.0,
                                fs_op=25.0), t=1.7e9, window_fill=1.0, samples=3600)
    b = _decode_block(result_block(st.results[0], code=4))
    assert (b["fd"], b["fs"]) == (pytest.approx(20.0), pytest.approx(25.0))
    assert b["jump"] == pytest.approx(9.95, rel=1e-6)
    reg = CollectorRegistry()
    reg.register(StoreCollector(st))
    assert reg.get_sample_value("stiction_loop_jump_ratio", {"loop": "FIC101"}) == \
        pytest.approx(0.0995)
    assert reg.get_sample_value("stiction_loop_fd_ratio", {"loop": "FIC101"}) == \
        pytest.approx(0.20)
