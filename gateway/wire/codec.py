"""Modbus register codec: numbers <-> 16-bit registers, vectorised with numpy.

Word order ``big`` means the most significant register comes first (the Modbus convention,
"ABCD"); byte order ``little`` means the two bytes inside each register are swapped ("BADC",
or "DCBA" with little word order). Used by the Modbus input (decode), the result server
(encode) and the simulated PLC (encode).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["TYPES", "decode_registers", "encode_values"]

# type -> (registers, numpy big-endian dtype)
TYPES: dict[str, tuple[int, str]] = {
    "int16": (1, ">i2"), "uint16": (1, ">u2"),
    "int32": (2, ">i4"), "uint32": (2, ">u4"),
    "float32": (2, ">f4"), "float64": (4, ">f8"),
}


def decode_registers(regs: NDArray[np.uint16], typ: str, word_order: str = "big",
                     byte_order: str = "big") -> NDArray[np.float64]:
    """Decode a (k, width) array of registers into k values (float64)."""
    width, dtype = TYPES[typ]
    regs = np.asarray(regs, dtype=np.uint16).reshape(-1, width)
    if word_order == "little":
        regs = regs[:, ::-1]
    raw = regs.astype(">u2" if byte_order == "big" else "<u2")  # bytes in MSB-first order
    with np.errstate(invalid="ignore"):  # a signalling NaN from the PLC is just a bad value
        return np.ascontiguousarray(raw).view(dtype).reshape(-1).astype(np.float64)


def encode_values(values: Any, typ: str, word_order: str = "big",
                  byte_order: str = "big") -> NDArray[np.uint16]:
    """Inverse of :func:`decode_registers`: k values → (k, width) registers (uint16)."""
    width, dtype = TYPES[typ]
    vals = np.asarray(values, dtype=np.float64).reshape(-1)
    if dtype[1] in "iu":
        vals = np.round(vals)
    raw = vals.astype(dtype).view(">u2" if byte_order == "big" else "<u2").reshape(-1, width)
    regs = raw.astype(np.uint16)
    return regs[:, ::-1].copy() if word_order == "little" else regs
