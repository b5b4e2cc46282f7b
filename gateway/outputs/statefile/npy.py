"""The state file's arrays into and out of its zip archive in pieces, so that neither a write
nor a read holds more than the arrays themselves and :data:`CHUNK_BYTES` (issue 38 item 4:
numpy's ``savez`` held a whole array's bytes beside it, a read each member's bytes beside
its array), and a read keeps only the rows and columns asked for (issue 35 item 7: a file
written for longer windows than the config has now is read trimmed to them)."""

from __future__ import annotations

import math
import zipfile
from collections.abc import Mapping, Sequence
from typing import Any, BinaryIO

import numpy as np
from numpy.typing import NDArray

__all__ = ["CHUNK_BYTES", "read_member", "savez", "shape_of"]

CHUNK_BYTES = 1 << 20
"""What a write or a read holds beside the arrays."""


def savez(f: BinaryIO, arrays: Mapping[str, NDArray[Any]]) -> None:
    """What ``np.savez`` writes (an uncompressed zip of ``.npy`` members, ZIP64; ``np.load``
    and every release's reader read it), each array written from itself in pieces."""
    with zipfile.ZipFile(f, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        for name, given in arrays.items():
            arr = np.ascontiguousarray(given)
            with zf.open(f"{name}.npy", "w", force_zip64=True) as out:
                np.lib.format.write_array_header_1_0(
                    out, np.lib.format.header_data_from_array_1_0(arr))
                data = arr.reshape(-1).view(np.uint8)
                for at in range(0, len(data), CHUNK_BYTES):
                    out.write(data[at:at + CHUNK_BYTES].tobytes())


def _open(archive: zipfile.ZipFile, info: zipfile.ZipInfo | None, dtype: np.dtype[Any],
          what: str) -> tuple[Any, tuple[int, ...]]:
    """The member opened past its ``.npy`` header, and its shape; ValueError if it is not an
    array of ``dtype`` in C order whose data fits what the member declares."""
    if info is None:
        raise ValueError(f"no {what}")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise ValueError(f"{what}: compression method {info.compress_type}")
    f = archive.open(info)
    try:
        version = np.lib.format.read_magic(f)
        read_head = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                     else np.lib.format.read_array_header_2_0)
        shape, fortran, found = read_head(f)
        if fortran or found != dtype:
            raise ValueError(f"{what}: {found} {'(Fortran order) ' if fortran else ''}where "
                             f"{dtype} belongs")
        if math.prod(shape) * dtype.itemsize > info.file_size:
            raise ValueError(f"{what}: shape {shape} needs more bytes than the member holds")
    except BaseException:
        f.close()
        raise
    return f, tuple(int(n) for n in shape)


def shape_of(archive: zipfile.ZipFile, info: zipfile.ZipInfo | None, dtype: np.dtype[Any],
             what: str) -> tuple[int, ...]:
    """A member's shape, from its ``.npy`` header alone (checked as :func:`read_member`)."""
    f, shape = _open(archive, info, dtype, what)
    f.close()
    return shape


def read_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo | None,
                dtype: np.dtype[Any], what: str, *, rows: int | None = None,
                columns: Sequence[int] | None = None) -> NDArray[Any]:
    """One ``.npy`` member of ``dtype``: its last ``rows`` rows (None: all) and, of a 2-D
    one, the ``columns`` given (None: all), read in pieces of whole rows; the rows before
    are read past, never kept. Never more than the member declares is unpacked."""
    f, shape = _open(archive, info, dtype, what)
    with f:
        total = shape[0] if shape else 1
        width = math.prod(shape[1:]) if len(shape) > 1 else 1
        row_bytes = width * dtype.itemsize
        keep = total if rows is None else min(rows, total)
        cols = None if columns is None or len(shape) != 2 else np.asarray(columns, np.intp)
        out_shape = (keep, *shape[1:]) if cols is None else (keep, len(cols))
        out = np.empty(out_shape if shape else (), dtype=dtype)
        if row_bytes == 0 or keep == 0:
            return out
        skip = (total - keep) * row_bytes
        while skip:  # rows not kept: read past them
            piece = f.read(min(CHUNK_BYTES, skip))
            if not piece:
                raise ValueError(f"{what}: truncated")
            skip -= len(piece)
        step = max(1, CHUNK_BYTES // row_bytes)
        flat = out.reshape(keep, -1) if out.ndim else out.reshape(1, 1)
        for lo in range(0, keep, step):
            n = min(step, keep - lo)
            piece = _exactly(f, n * row_bytes, what)
            block = np.frombuffer(piece, dtype=dtype).reshape(n, width)
            flat[lo:lo + n] = block if cols is None else block[:, cols]
    return out


def _exactly(f: Any, n: int, what: str) -> bytes:
    parts, left = [], n
    while left:
        piece = f.read(left)
        if not piece:
            raise ValueError(f"{what}: truncated")
        parts.append(piece)
        left -= len(piece)
    return parts[0] if len(parts) == 1 else b"".join(parts)
