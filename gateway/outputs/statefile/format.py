"""The state file: loop windows and latest assessments, so a restart loses (almost) nothing.

Format (version 1): a numpy ``.npz`` archive (zip of ``.npy`` arrays, loaded with
``allow_pickle=False``: no Python object is ever unpickled) holding

* ``header``: UTF-8 JSON as a uint8 array - ``format`` (``stiction-gateway-state``),
  ``version``, the wall and process time of the save, and per window bank its sample time,
  its loops (name + window signature) and per loop the latest assessment
  (:meth:`stiction.Assessment.to_dict`) with its sequence number, time and window fill,
  the loop's last sequence number, whether the write was the last before a normal exit
  (``clean``) and the analysis interval (how far sequence numbers may have moved on after
  an unclean exit);
* per bank ``bK_t`` (float64, rows), ``bK_op``/``bK_pv`` (float32, rows × loops) and
  ``bK_q`` (uint8 quality), the stored samples oldest first.

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
fresh and never crashes on it.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import time
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...config.model import Config
from ...core.store import ResultStore
from ...core.windows import LoopGroup, loop_signature, result_signature

__all__ = ["FORMAT", "VERSION", "StateError", "read_state", "set_aside", "snapshot",
           "write_state"]

FORMAT = "stiction-gateway-state"
VERSION = 1


class StateError(Exception):
    """The state file cannot be used; ``kind`` is ``corrupt`` or ``foreign``."""

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
        t, op, pv, q = b.bank.series(np.arange(len(b.configs)))
        arrays[f"b{k}_t"] = t
        arrays[f"b{k}_op"] = np.ascontiguousarray(op.T)
        arrays[f"b{k}_pv"] = np.ascontiguousarray(pv.T)
        arrays[f"b{k}_q"] = np.ascontiguousarray(q.T)
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
        header["banks"].append({"ts": b.ts, "size": b.bank.size, "loops": loops})
    return header, arrays


def write_state(path: str | os.PathLike[str], header: Mapping[str, Any],
                arrays: Mapping[str, NDArray[Any]]) -> int:
    """Write atomically (tmp + fsync + rename + fsync dir); returns the bytes written."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.tmp-{os.getpid()}")
    blob = np.frombuffer(json.dumps(header, allow_nan=True).encode(), dtype=np.uint8)
    try:
        with open(tmp, "wb") as f:
            np.savez(f, header=blob, **arrays)  # type: ignore[arg-type]
            f.flush()
            os.fsync(f.fileno())
            size = f.tell()
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    with contextlib.suppress(OSError):  # not every file system lets a directory be synced
        fd = os.open(target.parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    return size


# ------------------------------------------------------------------------ reading


def read_state(path: str | os.PathLike[str]) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """Read and check a state file; raise StateError (corrupt/foreign) if unusable."""
    try:
        data = Path(path).read_bytes()
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in npz.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise StateError("corrupt", f"not a readable state archive: {exc}") from None
    blob = arrays.pop("header", None)
    if blob is None or blob.dtype != np.uint8 or blob.ndim != 1:
        raise StateError("foreign", "no state header (not a stiction-gateway state file)")
    try:
        header = json.loads(blob.tobytes().decode())
    except (UnicodeDecodeError, ValueError) as exc:
        raise StateError("corrupt", f"unreadable header: {exc}") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise StateError("foreign", "not a stiction-gateway state file")
    if header.get("version") != VERSION:
        raise StateError("foreign", f"state format version {header.get('version')!r}, "
                         f"this gateway reads version {VERSION}")
    try:
        for k, b in enumerate(header["banks"]):
            n, rows = len(b["loops"]), len(arrays[f"b{k}_t"])
            for name in ("op", "pv", "q"):
                if arrays[f"b{k}_{name}"].shape != (rows, n):
                    raise ValueError(f"bank {k} {name} has shape "
                                     f"{arrays[f'b{k}_{name}'].shape}, expected {(rows, n)}")
            float(header["saved_wall"])
            float(header["saved_proc"])
    except (KeyError, TypeError, ValueError) as exc:
        raise StateError("corrupt", f"inconsistent content: {exc}") from None
    return header, arrays


def set_aside(path: Path, kind: str) -> Path:
    dest = path.with_name(f"{path.name}.{kind}-{time.strftime('%Y%m%dT%H%M%S')}")
    os.replace(path, dest)
    return dest
