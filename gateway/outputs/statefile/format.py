"""The state file: loop windows and latest assessments, so a restart loses (almost) nothing.

Format (version 2; version 1 files are still read): a numpy ``.npz`` archive (zip of
``.npy`` arrays, loaded with ``allow_pickle=False``: no Python object is ever unpickled)
holding

* ``header``: UTF-8 JSON as a uint8 array - ``format`` (``stiction-gateway-state``),
  ``version``, the wall and process time of the save, and per window bank its sample time,
  its loops (name + window signature) and per loop the latest assessment
  (:meth:`stiction.Assessment.to_dict`) with its sequence number, time and window fill,
  the loop's last sequence number, whether the write was the last before a normal exit
  (``clean``) and the analysis interval (how far sequence numbers may have moved on after
  an unclean exit);
* per bank ``bK_t`` (float64, rows), ``bK_op``/``bK_pv`` (float32, rows × loops) and
  ``bK_q`` (uint8 quality), the stored samples oldest first; and, new in version 2, where a
  loop of the bank reads the valve's position (the bank's ``"position": true``),
  ``bK_pos`` (float32, rows × loops; NaN where a loop has none or the sample was not GOOD).

Version 1 (before the position existed) is version 2 without ``bK_pos`` and without the
bank's ``position`` key: such a file restores as it did, the positions of its windows empty
(NaN), so a loop given a ``position`` since starts measuring the travel as samples come.

Writes are atomic: a temporary file in the same directory, ``fsync``, ``rename`` over the
old file, ``fsync`` of the directory. A crash (even SIGKILL) leaves either the previous file
or the new one, so at most one persistence interval is lost.

On start the file is restored loop by loop: a loop's window comes back when its *window
signature* (device connection and sample time, window length, OP/PV point definitions) is
unchanged, and its latest assessment when the whole loop config is also unchanged; other
loops start fresh. The time the gateway was down becomes a gap (quality MISSING) in the
restored windows. A file that cannot be read (truncated, not an archive, bad header) or
that is not ours (other format or version) is renamed aside
(``<file>.corrupt-<time>`` / ``<file>.foreign-<time>``) with a warning; the gateway starts
fresh and never crashes on it. The file is untrusted input: its size and the sizes its
members would unpack to are bounded (:func:`state_bounds`) before anything is decompressed,
and every field is checked (:mod:`.validate`) before anything is restored.
"""

from __future__ import annotations

import errno
import json
import math
import os
import time
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from numpy.typing import NDArray

from ...config.model import Config
from ...config.reading import open_regular
from ...core.points import Quality
from ...core.store import ResultStore
from ...core.windows import LoopGroup, loop_signature, result_signature
from ..base import write_atomically
from .validate import check_header

__all__ = ["FORMAT", "VERSION", "StateError", "read_state", "set_aside", "snapshot",
           "state_bounds", "write_state"]

FORMAT = "stiction-gateway-state"
VERSION = 2
READ_VERSIONS = (1, 2)  # what read_state accepts: version 1 has no positions


class StateError(Exception):
    """The state file cannot be used; ``kind`` is ``corrupt`` or ``foreign`` (set aside), or
    ``unreadable`` (not a regular file, or the file system did not answer in time: left
    where it is, the next write replaces it)."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


# ------------------------------------------------------------------------ writing


def snapshot(config: Config, banks: Sequence[LoopGroup], store: ResultStore, *,
             wall: float, proc: float, clean: bool = False
             ) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """Copy everything to persist (fast, on the event loop); write it with write_state.
    ``clean``: the last write before a normal exit (no assessment can follow it)."""
    g = config.gateway
    header: dict[str, Any] = {"format": FORMAT, "version": VERSION, "saved_wall": wall,
                              "saved_proc": proc, "clean": clean,
                              "analysis_interval_wall_s": g.analysis_interval_s / g.time_scale,
                              "banks": []}
    arrays: dict[str, NDArray[Any]] = {}
    for k, b in enumerate(banks):
        # one copy of the windows (issue 38 item 4: a chronological copy and then a
        # transposed one held three times the windows at each write)
        t, op, pv, q, pos = b.bank.rows()
        arrays[f"b{k}_t"], arrays[f"b{k}_op"], arrays[f"b{k}_pv"] = t, op, pv
        arrays[f"b{k}_q"] = q
        if pos is not None:
            arrays[f"b{k}_pos"] = pos
        loops = []
        for cfg in b.configs:
            entry: dict[str, Any] = {"name": cfg.name,
                                     "signature": loop_signature(config, cfg),
                                     "result_signature": result_signature(config, cfg)}
            i = store.index.get(cfg.name)
            res = store.results[i] if i is not None else None
            if i is not None:
                entry["seq"] = store.last_seq(i)
            if res is not None:
                entry["result"] = {"assessment": res.assessment.to_dict(), "seq": res.seq,
                                   "t": res.t, "window_fill": res.window_fill,
                                   "samples": res.samples}
            loops.append(entry)
        header["banks"].append({"ts": b.ts, "size": b.bank.size, "loops": loops,
                                **({} if pos is None else {"position": True})})
    return header, arrays


def write_state(path: str | os.PathLike[str], header: Mapping[str, Any],
                arrays: Mapping[str, NDArray[Any]]) -> int:
    """Write atomically (:func:`gateway.outputs.base.write_atomically`: tmp + fsync + rename
    + fsync dir); returns the bytes written."""
    blob = np.frombuffer(json.dumps(header, allow_nan=True).encode(), dtype=np.uint8)
    return write_atomically(path, lambda f: _savez(f, {"header": blob, **arrays}))


CHUNK_BYTES = 1 << 20
"""What a write or a read of the state file holds beside the arrays (numpy's own savez
held a whole array's bytes, up to 16 MiB, and a read each member's bytes beside its array)."""


def _savez(f: BinaryIO, arrays: Mapping[str, NDArray[Any]]) -> None:
    """What ``np.savez`` writes (an uncompressed zip of ``.npy`` members, ZIP64), each
    array's data written from the array in :data:`CHUNK_BYTES` pieces, never copied whole."""
    with zipfile.ZipFile(f, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        for name, arr in arrays.items():
            arr = np.ascontiguousarray(arr)
            with zf.open(f"{name}.npy", "w", force_zip64=True) as out:
                np.lib.format.write_array_header_1_0(
                    out, np.lib.format.header_data_from_array_1_0(arr))
                data = arr.reshape(-1).view(np.uint8)
                for at in range(0, len(data), CHUNK_BYTES):
                    out.write(data[at:at + CHUNK_BYTES].tobytes())


# ------------------------------------------------------------------------ reading


DEFAULT_MAX_BYTES = 2**30  # read_state's bound when the caller gives none
HEADER_BYTES_PER_LOOP = 16 * 1024  # a loop's entry, its latest assessment included, is ~2 KiB
_DTYPES: dict[str, np.dtype[Any]] = {
    "t": np.dtype("<f8"), "op": np.dtype("<f4"), "pv": np.dtype("<f4"), "q": np.dtype("u1")}


def state_bounds(banks: Sequence[LoopGroup]) -> tuple[int, int]:
    """``(bytes, loops)``: the most a state file read for these windows may unpack to and
    the most loop entries it may hold: twice what the windows hold, plus 16 MiB and 16 KiB
    of header per loop (room for a file written before some loops were removed)."""
    loops = sum(len(g.configs) for g in banks)
    windows = sum(g.bank.nbytes for g in banks)
    return 2 * windows + HEADER_BYTES_PER_LOOP * max(loops, 1) + 16 * 2**20, 2 * loops + 100


def read_state(path: str | os.PathLike[str], *, max_bytes: int = DEFAULT_MAX_BYTES,
               max_loops: int = 1_000_000
               ) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """Read and check a state file; raise StateError (corrupt/foreign) if unusable.

    The file is untrusted: it is refused unread beyond ``max_bytes``, its members are
    refused when the sizes they declare (what they would unpack to) exceed ``max_bytes``
    in all, *before* anything is decompressed; every array must have the type and shape
    its bank's header says, every header field its type and range
    (:func:`.validate.check_header`), with at most ``max_loops`` loops."""
    try:
        fh = open_regular(path)  # never a FIFO: it would block the read
    except OSError as exc:
        kind = "unreadable" if exc.errno == errno.EINVAL else "corrupt"
        raise StateError(kind, f"cannot read it: {exc.strerror or exc}") from None
    with fh:
        return _read_archive(fh, max_bytes=max_bytes, max_loops=max_loops)


def _read_archive(fh: BinaryIO, *, max_bytes: int, max_loops: int
                  ) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    size = os.fstat(fh.fileno()).st_size
    if size > max_bytes:
        raise StateError("corrupt", f"{size:,} bytes, more than the {max_bytes:,} a state "
                         f"file of this config can need")
    try:
        archive = zipfile.ZipFile(fh)  # read member by member: never the whole file at once
    except Exception as exc:  # untrusted bytes: whatever zipfile makes of them
        raise StateError("corrupt", f"not a readable state archive: {exc}") from None
    with archive:
        try:
            members = {i.filename: i for i in archive.infolist()}
            declared = sum(i.file_size for i in members.values())
            if len(members) != len(archive.infolist()) or len(members) > 4 * max_loops + 1:
                raise ValueError(f"{len(archive.infolist()):,} members")
            if declared > max_bytes:
                raise ValueError(f"its members would unpack to {declared:,} bytes, more "
                                 f"than the {max_bytes:,} a state file of this config can "
                                 f"need (not unpacked)")
        except ValueError as exc:
            raise StateError("corrupt", str(exc)) from None
        if "header.npy" not in members:
            raise StateError("foreign", "no state header (not a stiction-gateway state file)")
        try:
            blob = _array(archive, members["header.npy"], np.dtype("u1"), "header")
            header = json.loads(blob.tobytes().decode())
        except Exception as exc:
            raise StateError("corrupt", f"unreadable header: {exc}") from None
        if not isinstance(header, dict) or header.get("format") != FORMAT:
            raise StateError("foreign", "not a stiction-gateway state file")
        if header.get("version") not in READ_VERSIONS:
            raise StateError("foreign", f"state format version {header.get('version')!r}, "
                             f"this gateway reads versions "
                             f"{', '.join(map(str, READ_VERSIONS))}")
        try:
            check_header(header, max_loops)
            arrays = _bank_arrays(archive, members, header["banks"])
        except Exception as exc:
            raise StateError("corrupt", f"inconsistent content: {exc}") from None
    return header, arrays


def _bank_arrays(archive: zipfile.ZipFile, members: Mapping[str, zipfile.ZipInfo],
                 banks: Sequence[Mapping[str, Any]]) -> dict[str, NDArray[Any]]:
    arrays: dict[str, NDArray[Any]] = {}
    for k, b in enumerate(banks):
        n = len(b["loops"])
        names = dict(_DTYPES)
        if b.get("position") is True:  # version 2: the bank holds positions
            names["pos"] = np.dtype("<f4")
        for name, dtype in names.items():
            key = f"b{k}_{name}"
            arr = _array(archive, members.get(f"{key}.npy"), dtype, key)
            rows = len(arrays[f"b{k}_t"]) if name != "t" else len(arr)
            want = (rows,) if name == "t" else (rows, n)
            if arr.shape != want:
                raise ValueError(f"bank {k} {name} has shape {arr.shape}, expected {want}")
            arrays[key] = arr
        if len(arrays[f"b{k}_t"]) > b["size"]:
            raise ValueError(f"bank {k} holds {len(arrays[f'b{k}_t'])} samples, more than "
                             f"its size {b['size']}")
        if not np.isfinite(arrays[f"b{k}_t"]).all():
            raise ValueError(f"bank {k}: a sample time is not finite")
        if arrays[f"b{k}_q"].size and int(arrays[f"b{k}_q"].max()) > max(Quality):
            raise ValueError(f"bank {k}: a quality code above {int(max(Quality))}")
    extra = set(members) - {"header.npy"} - {f"{key}.npy" for key in arrays}
    if extra:
        raise ValueError(f"unexpected members {sorted(extra)[:5]}")
    return arrays


def _array(archive: zipfile.ZipFile, info: zipfile.ZipInfo | None, dtype: np.dtype[Any],
           what: str) -> NDArray[Any]:
    """One ``.npy`` member of ``dtype``, its size checked against what the member declares
    before its data is read (never more than that is unpacked)."""
    if info is None:
        raise ValueError(f"no {what}")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise ValueError(f"{what}: compression method {info.compress_type}")
    with archive.open(info) as f:
        version = np.lib.format.read_magic(f)
        read_head = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                     else np.lib.format.read_array_header_2_0)
        shape, fortran, found = read_head(f)
        if fortran or found != dtype:
            raise ValueError(f"{what}: {found} {'(Fortran order) ' if fortran else ''}where "
                             f"{dtype} belongs")
        nbytes = math.prod(shape) * dtype.itemsize
        if nbytes > info.file_size:
            raise ValueError(f"{what}: shape {shape} needs more bytes than the member holds")
        arr = np.empty(shape, dtype=dtype)
        into = arr.reshape(-1).view(np.uint8)
        at = 0
        while at < nbytes:  # in pieces: never the member's bytes beside the array
            piece = f.read(min(CHUNK_BYTES, nbytes - at))
            if not piece:
                raise ValueError(f"{what}: truncated")
            into[at:at + len(piece)] = np.frombuffer(piece, dtype=np.uint8)
            at += len(piece)
    return arr


def set_aside(path: Path, kind: str) -> Path:
    dest = path.with_name(f"{path.name}.{kind}-{time.strftime('%Y%m%dT%H%M%S')}")
    os.replace(path, dest)
    return dest
