"""The state file: loop windows and latest assessments, so a restart loses (almost) nothing.

Format (version 2; version 1 files are still read, and written where nothing of version 2 is
in the file, no bank holding positions: the release before version 2 reads them, so a
downgrade keeps the windows, verdicts and sequence numbers; issue 35 item 7): a numpy
``.npz`` archive (zip of ``.npy`` arrays, loaded with ``allow_pickle=False``: no Python
object is ever unpickled) holding

* ``header``: UTF-8 JSON as a uint8 array - ``format`` (``stiction-gateway-state``),
  ``version``, the wall and process time of the save, the loops in config order (``order``:
  a restart with them in another order says register +19 numbers them anew), the plant
  view's roles where there are groups (``plant``: per loop its group number, role and
  source loop, for ``stiction-gateway report``; not restored), and per window bank its
  sample time,
  its loops (name + window signature) and per loop the latest assessment
  (:meth:`stiction.Assessment.to_dict`) with its sequence number, time and window fill
  (and, read when present, when its verdict was judged and whether it was held: a held
  verdict's age survives a restart),
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
signature* (device connection and sample time, OP/PV point definitions; the window's length
aside: a window saved longer than it is now comes back trimmed to its newest samples) is
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
import os
import time
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from stiction import Assessment, Verdict

from ...config.model import Config
from ...config.reading import open_regular
from ...core.points import Quality
from ...core.store import ResultStore
from ...core.windows import LoopGroup, loop_signature, result_signature
from ..base import write_atomically
from .npy import read_member, savez, shape_of
from .validate import check_header

__all__ = ["FORMAT", "VERSION", "StateError", "read_state", "set_aside", "snapshot",
           "state_bounds", "write_state"]

FORMAT = "stiction-gateway-state"
VERSION = 2
READ_VERSIONS = (1, 2)  # what read_state accepts: version 1 has no positions
V1_ASSESSMENT = frozenset({
    "verdict", "reason", "oscillating", "period_s", "stiction_index", "fd", "fs", "jump",
    "fd_op", "fs_op", "cycles_used", "multi_jump", "warnings", "confidence", "evidence",
    "band", "band_op"})
"""The assessment fields the release that reads version 1 only knows (it refuses a file
with any other: :func:`snapshot` writes version 2 where one holds a value)."""
_DEFAULTS = Assessment(Verdict.UNDETERMINED, "").to_dict()


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
    header: dict[str, Any] = {"format": FORMAT, "version": 1, "saved_wall": wall,
                              "saved_proc": proc, "clean": clean,
                              "analysis_interval_wall_s": g.analysis_interval_s / g.time_scale,
                              "order": list(store.loops), "banks": []}
    arrays: dict[str, NDArray[Any]] = {}
    plant = {name: [*store.plant.of(name)[:2], store.plant.of(name)[2] or ""]
             for name in store.plant.roles if name in store.index}
    if plant:  # who drives whom, for the report (issue 39; the release before ignores it)
        header["plant"] = plant
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
                a = res.assessment.to_dict()
                if any(a[k] != _DEFAULTS.get(k) for k in a if k not in V1_ASSESSMENT):
                    header["version"] = VERSION
                entry["result"] = {"assessment": a, "seq": res.seq, "t": res.t,
                                   "window_fill": res.window_fill, "samples": res.samples,
                                   "judged": res.judged_at, "hold": res.hold,
                                   **_listed(res)}
            loops.append(entry)
        header["banks"].append({"ts": b.ts, "size": b.bank.size, "loops": loops,
                                **({} if pos is None else {"position": True})})
        if pos is not None:
            header["version"] = VERSION
    if header["version"] == 1:  # what the previous release reads: nothing new in it
        for bank in header["banks"]:
            for entry in bank["loops"]:
                if "result" in entry:
                    a = entry["result"]["assessment"]
                    entry["result"]["assessment"] = {k: v for k, v in a.items()
                                                     if k in V1_ASSESSMENT}
    return header, arrays


def _listed(res: Any) -> dict[str, float]:
    """What the list worst first reads of a result (issue 39; the release before ignores
    both): the PV's swing and since when the loop has had its verdict, where known."""
    return {k: float(v) for k, v in (("pv_swing", res.pv_swing), ("since", res.since))
            if v is not None and np.isfinite(v)}


def write_state(path: str | os.PathLike[str], header: Mapping[str, Any],
                arrays: Mapping[str, NDArray[Any]]) -> int:
    """Write atomically (:func:`gateway.outputs.base.write_atomically`: tmp + fsync + rename
    + fsync dir); returns the bytes written."""
    blob = np.frombuffer(json.dumps(header, allow_nan=True).encode(), dtype=np.uint8)
    return write_atomically(path, lambda f: savez(f, {"header": blob, **arrays}))



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
               max_loops: int = 1_000_000, keep: Mapping[str, int] | None = None
               ) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """Read and check a state file; raise StateError (corrupt, foreign; unreadable: not a
    regular file) if unusable.

    ``keep`` (the restore's): per loop name the samples its window holds now; each bank is
    read trimmed to the loops named (their columns) and the newest samples the longest of
    them holds (issue 35 item 7: a file written for longer windows than the config has now
    was set aside as too large), the rest read past; the header's banks then list only the
    loops kept. Without ``keep`` everything is read.

    The file is untrusted: what is kept must fit ``max_bytes``, and a compressed member
    (never written by the gateway) must not declare more than that, before anything is
    decompressed (a zip bomb); without ``keep``, the file and its members in all must fit
    ``max_bytes``. Every array must have the type and shape its bank's header says, every
    header field its type and range (:func:`.validate.check_header`), with at most
    ``max_loops`` loops."""
    try:
        fh = open_regular(path)  # never a FIFO: it would block the read
    except OSError as exc:
        kind = "unreadable" if exc.errno == errno.EINVAL else "corrupt"
        raise StateError(kind, f"cannot read it: {exc.strerror or exc}") from None
    with fh:
        size = os.fstat(fh.fileno()).st_size
        if keep is None and size > max_bytes:
            raise StateError("corrupt", f"{size:,} bytes, more than the {max_bytes:,} a state "
                             f"file of this config can need")
        try:
            archive = zipfile.ZipFile(fh)  # member by member: never the whole file at once
        except Exception as exc:  # untrusted bytes: whatever zipfile makes of them
            raise StateError("corrupt", f"not a readable state archive: {exc}") from None
        with archive:
            members = _members(archive, max_bytes, max_loops, whole=keep is None)
            header = _header(archive, members, max_loops)
            try:
                check_header(header, max_loops)
                arrays = _bank_arrays(archive, members, header["banks"], keep, max_bytes)
            except Exception as exc:
                raise StateError("corrupt", f"inconsistent content: {exc}") from None
    return header, arrays


def _members(archive: zipfile.ZipFile, max_bytes: int, max_loops: int, *, whole: bool
             ) -> dict[str, zipfile.ZipInfo]:
    try:
        members = {i.filename: i for i in archive.infolist()}
        if len(members) != len(archive.infolist()) or len(members) > 4 * max_loops + 1:
            raise ValueError(f"{len(archive.infolist()):,} members")
        declared = sum(i.file_size for i in members.values()
                       if whole or i.compress_type != zipfile.ZIP_STORED)
        if declared > max_bytes:
            raise ValueError(f"its {'members' if whole else 'compressed members'} would "
                             f"unpack to {declared:,} bytes, more than the {max_bytes:,} a "
                             f"state file of this config can need (not unpacked)")
        head = members.get("header.npy")
        if head is not None and head.file_size > HEADER_BYTES_PER_LOOP * max_loops + 2**20:
            raise ValueError(f"a header of {head.file_size:,} bytes, more than "
                             f"{max_loops:,} loops can need")
    except ValueError as exc:
        raise StateError("corrupt", str(exc)) from None
    if "header.npy" not in members:
        raise StateError("foreign", "no state header (not a stiction-gateway state file)")
    return members


def _header(archive: zipfile.ZipFile, members: Mapping[str, zipfile.ZipInfo],
            max_loops: int) -> dict[str, Any]:
    try:
        blob = read_member(archive, members["header.npy"], np.dtype("u1"), "header")
        header = json.loads(blob.tobytes().decode())
    except Exception as exc:
        raise StateError("corrupt", f"unreadable header: {exc}") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise StateError("foreign", "not a stiction-gateway state file")
    if header.get("version") not in READ_VERSIONS:
        raise StateError("foreign", f"state format version {header.get('version')!r}, "
                         f"this gateway reads versions "
                         f"{', '.join(map(str, READ_VERSIONS))}")
    return header


def _bank_arrays(archive: zipfile.ZipFile, members: Mapping[str, zipfile.ZipInfo],
                 banks: list[dict[str, Any]], keep: Mapping[str, int] | None,
                 max_bytes: int) -> dict[str, NDArray[Any]]:
    arrays: dict[str, NDArray[Any]] = {}
    kept_bytes = 0
    for k, b in enumerate(banks):
        n = len(b["loops"])
        names = dict(_DTYPES)
        if b.get("position") is True:  # version 2: the bank holds positions
            names["pos"] = np.dtype("<f4")
        total, *_ = shape_of(archive, members.get(f"b{k}_t.npy"), names["t"], f"b{k}_t")
        if total > b["size"]:
            raise ValueError(f"bank {k} holds {total} samples, more than its size {b['size']}")
        cols, rows = list(range(n)), total
        if keep is not None:  # the loops of today's config, the samples they hold today
            cols = [c for c, e in enumerate(b["loops"]) if e.get("name") in keep]
            rows = min(total, max((keep[b["loops"][c]["name"]] for c in cols), default=0))
        for name, dtype in names.items():
            key = f"b{k}_{name}"
            info = members.get(f"{key}.npy")
            want = (total,) if name == "t" else (total, n)
            if (shape := shape_of(archive, info, dtype, key)) != want:
                raise ValueError(f"bank {k} {name} has shape {shape}, expected {want}")
            kept_bytes += rows * (1 if name == "t" else len(cols)) * dtype.itemsize
            if kept_bytes > max_bytes:
                raise ValueError(f"more than the {max_bytes:,} bytes of windows this config "
                                 "can hold")
            arrays[key] = (read_member(archive, info, dtype, key, rows=rows, columns=cols)
                           if rows else np.empty((0,) + ((len(cols),) if name != "t" else ()),
                                                 dtype=dtype))
        if not np.isfinite(arrays[f"b{k}_t"]).all():
            raise ValueError(f"bank {k}: a sample time is not finite")
        if arrays[f"b{k}_q"].size and int(arrays[f"b{k}_q"].max()) > max(Quality):
            raise ValueError(f"bank {k}: a quality code above {int(max(Quality))}")
        if keep is not None:
            b["loops"] = [b["loops"][c] for c in cols]
    extra = set(members) - {"header.npy"} - {f"{key}.npy" for key in arrays}
    if extra:
        raise ValueError(f"unexpected members {sorted(extra)[:5]}")
    return arrays


def set_aside(path: Path, kind: str) -> Path:
    dest = path.with_name(f"{path.name}.{kind}-{time.strftime('%Y%m%dT%H%M%S')}")
    os.replace(path, dest)
    return dest
