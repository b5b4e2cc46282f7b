"""wire.codec: registers <-> numbers, every type and word/byte order."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gateway.wire.codec import TYPES, decode_registers, encode_values

ORDERS = ["big", "little"]


def test_decode_known_layouts() -> None:
    # 123.456 as float32 is 0x42F6E979: ABCD big/big, CDAB little words, BADC swapped bytes
    assert decode_registers(np.array([0x42F6, 0xE979]), "float32")[0] == pytest.approx(123.456)
    assert decode_registers(np.array([0xE979, 0x42F6]), "float32", "little")[0] == \
        pytest.approx(123.456)
    assert decode_registers(np.array([0xF642, 0x79E9]), "float32", "big", "little")[0] == \
        pytest.approx(123.456)
    assert decode_registers(np.array([0x79E9, 0xF642]), "float32", "little", "little")[0] == \
        pytest.approx(123.456)
    assert decode_registers(np.array([0xFFFF]), "int16")[0] == -1
    assert decode_registers(np.array([0xFFFF]), "uint16")[0] == 65535
    assert decode_registers(np.array([0xFFFF, 0xFFFE]), "int32")[0] == -2
    assert decode_registers(np.array([0x0001, 0x0000]), "uint32")[0] == 65536
    regs = np.frombuffer(struct.pack(">d", -2.5), dtype=">u2").astype(np.uint16)
    assert decode_registers(regs, "float64")[0] == -2.5


@settings(max_examples=200, deadline=None, derandomize=True)
@given(typ=st.sampled_from(sorted(TYPES)), word=st.sampled_from(ORDERS),
       byte=st.sampled_from(ORDERS), seed=st.integers(0, 2**32 - 1))
def test_encode_decode_round_trip(typ: str, word: str, byte: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    width, dtype = TYPES[typ]
    if dtype[1] == "f":
        values = rng.normal(0, 1e3, 8).astype(dtype).astype(np.float64)
    else:
        info = np.iinfo(np.dtype(dtype))
        values = rng.integers(info.min, info.max, 8, endpoint=True).astype(np.float64)
    regs = encode_values(values, typ, word, byte)
    assert regs.shape == (8, width)
    np.testing.assert_array_equal(decode_registers(regs, typ, word, byte), values)
