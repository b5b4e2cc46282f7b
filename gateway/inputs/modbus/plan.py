"""Request planning: the fewest Modbus read requests that cover a device's points.

Per table the points' register spans are merged into ranges (spans at most ``merge_gap``
registers apart join; the gap is read and ignored) and each range is cut into requests of at
most ``max_registers`` registers. A point may straddle two requests: the responses land in
one flat register image, and :func:`plan_requests` says where each point starts in it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .config import MAX_REGISTERS, TABLES, ModbusPoint

__all__ = ["ReadRequest", "plan_requests"]


@dataclasses.dataclass(frozen=True)
class ReadRequest:
    table: str
    address: int
    count: int
    offset: int  # where the answer lands in the flat register image


def plan_requests(points: Sequence[ModbusPoint], max_registers: int = MAX_REGISTERS,
                  merge_gap: int = 0) -> tuple[list[ReadRequest], NDArray[np.intp]]:
    """The read requests for ``points`` and each point's first register in the image.

    Per table the registers used are merged into ranges (gaps up to ``merge_gap`` joined);
    each range of R registers costs ceil(R / max_registers) requests, the minimum."""
    requests: list[ReadRequest] = []
    first = np.zeros(len(points), dtype=np.intp)
    offset = 0
    for table in TABLES:
        idx = [i for i, p in enumerate(points) if p.table == table]
        if not idx:
            continue
        spans = sorted((points[i].address, points[i].address + points[i].width) for i in idx)
        ranges: list[list[int]] = []
        for lo, hi in spans:
            if ranges and lo <= ranges[-1][1] + merge_gap:
                ranges[-1][1] = max(ranges[-1][1], hi)
            else:
                ranges.append([lo, hi])
        range_offset: list[tuple[int, int, int]] = []
        for lo, hi in ranges:
            range_offset.append((lo, hi, offset))
            for start in range(lo, hi, max_registers):
                count = min(max_registers, hi - start)
                requests.append(ReadRequest(table, start, count, offset + start - lo))
            offset += hi - lo
        starts = np.array([r[0] for r in range_offset])
        for i in idx:
            k = int(np.searchsorted(starts, points[i].address, side="right")) - 1
            lo, _hi, off = range_offset[k]
            first[i] = off + points[i].address - lo
    return requests, first
