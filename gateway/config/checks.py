"""What ``run`` would refuse or crash on, refused at load (so ``check-config`` says it first).

Each check adds one problem line naming the section and the key:

* **memory**: what ``run`` holds at its peak (:func:`memory_bytes`: the loop windows as
  allocated, positions included, a copy of them for a state write, a restore or a reload,
  the analysis' copies in flight, and the plant step, :func:`plant_bytes`; issue 38 item 4,
  tests/config/test_memory_count.py measures it) must fit ``gateway.memory_limit_mb``
  (default: half of this machine's memory, or of the service's memory limit if lower).
  ``window_s: 1e9`` or ``poll_interval_s: 1e-6`` would otherwise end in MemoryError at
  start, or in the machine swapping; so would 2,000 loops of 65,536-sample windows with
  ``plant.max_samples: 65536`` (about 10 GiB in the plant step).
* **state file**: ``gateway.state_file`` must not be the config file (the gateway would
  overwrite it) nor an existing file that is not a state file (anything but an empty file
  or a zip archive: a state file that cannot be read is set aside, a stranger's file must
  not be).
* **listeners**: ``metrics.listen`` and ``modbus_server.listen`` must not share a port on
  overlapping addresses.
* **file descriptors**: the connections the servers may hold plus the devices and workers
  must fit the process's limit (``LimitNOFILE`` of the unit): :func:`fds_needed`.

:func:`bind_check` (``check-config --bind-check``) also tries to bind both listeners.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import resource
import socket
from pathlib import Path
from typing import Any

from ..wire.registers import IDENTIFICATION_OBJECTS
from .model import Config
from .reading import bounded, open_regular
from .schema import Problems

__all__ = [
    "FDS_BASE",
    "FDS_PER_DEVICE",
    "FDS_PER_WORKER",
    "analysis_copy_bytes",
    "bind_check",
    "check_config",
    "default_memory_limit_mb",
    "fds_needed",
    "identification",
    "machine_memory_bytes",
    "memory_bytes",
    "plant_bytes",
    "window_bytes",
]

FDS_BASE = 64  # interpreter, log, state file, the workers' queues, sd_notify
FDS_PER_DEVICE = 2  # a connection (OPC UA: and the endpoint probe)
FDS_PER_WORKER = 2  # a process sentinel and its share of the pool's pipes
WILDCARDS = frozenset({"", "0.0.0.0", "::", "*"})
PLANT_BYTES_PER_SAMPLE = 112
"""Bytes per loop and averaged sample the plant step holds at its peak: the job and its
pickle in the gateway (float32 OP and PV, 16 in all) and, in the worker, the job again and
the analysis' matrices (float64 signals, spectra and their sums: 45-83 measured from 2,000
to 3,300,000 loop-samples; tests/config/test_plant_memory.py fails if this is too low)."""
ANALYSIS_BATCH_LOOPS = 64
"""Loops per batch of an analysis round (the scheduler's default ``batch_size``)."""
PLANT_BYTES_FIXED = 8 * 2**20
"""Bytes the plant step of one time base holds whatever its size (the groups' evidence)."""
MAX_IDENTIFICATION_CHARS = 30  # 7 objects fit one Modbus answer (253 bytes)


def check_config(problems: Problems, config: Config) -> None:
    """Add a problem line for each check of the module docstring that ``config`` fails."""
    _check_memory(problems, config)
    _check_state_file(problems, config)
    _check_listeners(problems, config)
    _check_fds(problems, config)


# ---------------------------------------------------------------------------- memory


def machine_memory_bytes() -> int:
    """Physical memory, or the cgroup's memory limit (systemd ``MemoryMax=``) if lower."""
    total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        with contextlib.suppress(OSError, ValueError):
            total = min(total, int(Path(path).read_text().strip()))
    return int(total)


def default_memory_limit_mb() -> float:
    """``gateway.memory_limit_mb`` when not set: half of :func:`machine_memory_bytes`."""
    return machine_memory_bytes() / 2 / 2**20


def _banks(config: Config) -> dict[tuple[str, int], tuple[int, bool]]:
    """The window banks ``run`` makes (one per device and window length, as
    ``runtime.reload`` groups them): (device, samples) -> (loops, whether any reads the
    valve's position)."""
    banks: dict[tuple[str, int], tuple[int, bool]] = {}
    for lp in config.loops:
        key = (lp.device, config.window_samples(lp))
        loops, pos = banks.get(key, (0, False))
        banks[key] = (loops + 1, pos or lp.position is not None)
    return banks


def window_bytes(config: Config) -> int:
    """Bytes of every loop window, exactly as ``run`` allocates them: per bank (a device and
    a window length) 9 per sample and loop (float32 OP and PV, a quality byte), 4 more per
    sample and loop when any loop of the bank reads the valve's position (the bank then holds
    a position for every loop of it), and 8 per sample (a time stamp)."""
    return sum(n * (loops * (13 if pos else 9) + 8)
               for (_dev, n), (loops, pos) in _banks(config).items())


def analysis_copy_bytes(config: Config) -> int:
    """Bytes of the windows an analysis round holds copied at once: at most 2 batches per
    worker in flight (the largest of the round's), each at most
    :data:`ANALYSIS_BATCH_LOOPS` loops of one bank, twice (the jobs and their pickles)."""
    workers = config.gateway.analysis_workers or max(1, (os.cpu_count() or 2) - 1)
    sizes = []
    for (_dev, n), (loops, pos) in _banks(config).items():
        for lo in range(0, loops, ANALYSIS_BATCH_LOOPS):
            sizes.append(min(ANALYSIS_BATCH_LOOPS, loops - lo) * n * (13 if pos else 9)
                         + 8 * n)
    return 2 * sum(sorted(sizes, reverse=True)[:2 * workers])


def memory_bytes(config: Config) -> dict[str, int]:
    """What ``check-config`` counts against ``gateway.memory_limit_mb``: the data ``run``
    holds at its peak (its interpreters, about 100 MiB per process, are the rest of the
    default budget). ``windows`` (:func:`window_bytes`); ``copy``, one more copy of them:
    a state write's snapshot, the arrays read at a restore, or a reload's new windows beside
    the old (never two at once: a reload waits for a state write); ``analysis``
    (:func:`analysis_copy_bytes`) and ``plant`` (:func:`plant_bytes`), which may run
    during a state write."""
    windows = window_bytes(config)
    return {"windows": windows, "copy": windows, "analysis": analysis_copy_bytes(config),
            "plant": plant_bytes(config)[0]}


def plant_bytes(config: Config) -> tuple[int, tuple[int, int] | None]:
    """Bytes the plant step holds at its peak, every time base's job at once (each loop's
    window averaged down to at most ``plant.max_samples``), and the largest job's (loops,
    samples); (0, None) with ``plant.enabled: false``."""
    if not config.plant.enabled:
        return 0, None
    bases: dict[tuple[float, int], int] = {}
    for lp in config.loops:
        key = (config.device(lp.device).poll_interval_s, config.window_samples(lp))
        bases[key] = bases.get(key, 0) + 1
    total = 0
    largest: tuple[int, int] | None = None
    for (_ts, length), loops in bases.items():
        if loops < 2:
            continue
        width = length // math.ceil(length / config.plant.max_samples)
        total += PLANT_BYTES_FIXED + PLANT_BYTES_PER_SAMPLE * loops * width
        if largest is None or loops * width > largest[0] * largest[1]:
            largest = (loops, width)
    return total, largest


def _gib(n: float) -> str:
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.1f} MiB"


def _check_memory(problems: Problems, config: Config) -> None:
    limit_mb = config.gateway.memory_limit_mb
    origin = "gateway.memory_limit_mb"
    if limit_mb is None:
        limit_mb, origin = default_memory_limit_mb(), "half this machine's memory"
    budget = limit_mb * 2**20
    parts = memory_bytes(config)
    windows = parts["windows"] + parts["copy"] + parts["analysis"]
    plant = parts["plant"]
    if windows + plant <= budget or not config.loops:
        return
    shown = f"{limit_mb:,.0f}" if limit_mb >= 10 else f"{limit_mb:g}"
    budget_text = f"the memory budget of {shown} MiB ({origin})"
    largest = plant_bytes(config)[1]
    if windows <= budget and largest is not None:
        loops, width = largest
        problems.add("plant", "max_samples",
                     f"the plant step needs {_gib(plant)} (its largest time base: {loops:,} "
                     f"loops x {width:,} samples); with the loop windows ({_gib(windows)}) "
                     f"that is {_gib(plant + windows)}, over {budget_text}: lower "
                     "plant.max_samples "
                     f"(now {config.plant.max_samples:,}), set plant.enabled: false or raise "
                     "gateway.memory_limit_mb")
        return
    big = max(config.loops, key=config.window_samples)
    n = config.window_samples(big)
    dev = config.device(big.device)
    what = (f"window_s {big.window_s:g} / poll_interval_s {dev.poll_interval_s:g} of device "
            f"{dev.name}")
    if 2 * 9 * n > budget:
        problems.add(f"loop {big.name}", "window_s",
                     f"its window of {n:,} samples ({what}) needs {_gib(2 * 9 * n)} with the "
                     f"state file's copy, over {budget_text}: shorten window_s or lengthen "
                     "poll_interval_s")
        return
    problems.add("gateway", "memory_limit_mb",
                 f"the loop windows need {_gib(windows)} with a copy of them (a state write, "
                 f"a reload) and the analysis' copies in flight, over {budget_text}; the "
                 f"largest is loop {big.name}'s, {n:,} samples ({what}): shorten window_s, "
                 "lengthen poll_interval_s or raise gateway.memory_limit_mb")


# ---------------------------------------------------------------------------- state file


def _check_state_file(problems: Problems, config: Config) -> None:
    try:  # a stat or an open on a hung mount never returns: bounded (config/reading.py)
        problem = bounded(_state_file_problem, Path(config.gateway.state_file),
                          Path(config.source))
    except OSError as exc:
        problem = f"{config.gateway.state_file}: {exc.strerror or exc}"
    if problem is not None:
        problems.add("gateway", "state_file", problem)


def _state_file_problem(state: Path, source: Path) -> str | None:
    if source.is_file() and (state.resolve() == source.resolve()
                             or (state.exists() and os.path.samefile(state, source))):
        return f"{state} is this config file: the gateway would overwrite it with its state"
    if state.is_dir():
        return f"{state} is a directory; name a file in it"
    if not state.exists():
        return None
    try:
        with open_regular(state) as fh:
            head = fh.read(4)
    except OSError as exc:
        if exc.errno == errno.EINVAL:  # a FIFO, a device: never a state file
            return f"{state} {exc.strerror}"
        return None  # unreadable: the gateway reports it when it starts
    if head not in (b"", b"PK\x03\x04"):  # empty, or a zip archive (maybe truncated, or a
        # foreign one: both are set aside at start with a warning)
        return (f"{state} exists and is not a gateway state file (not a zip archive): the "
                "gateway would set it aside and write its state there; name another file")
    return None


# ---------------------------------------------------------------------------- listeners


def _overlap(a: tuple[str, int], b: tuple[str, int]) -> bool:
    return a[1] == b[1] != 0 and (a[0] == b[0] or a[0] in WILDCARDS or b[0] in WILDCARDS)


def _check_listeners(problems: Problems, config: Config) -> None:
    m, r = config.metrics.listen, config.modbus_server.listen
    if _overlap(m, r):
        problems.add("metrics", "listen", f"{m[0]}:{m[1]} is the port of modbus_server.listen "
                     f"({r[0]}:{r[1]}): the two servers need two ports")


def bind_check(config: Config) -> list[str]:
    """Try to bind each listener (and let go at once); a problem line for each in use."""
    problems = Problems(config.source)
    for section, (host, port) in (("metrics", config.metrics.listen),
                                  ("modbus_server", config.modbus_server.listen)):
        try:
            with socket.create_server((host, port)):
                pass
        except OSError as exc:
            problems.add(section, "listen", f"cannot listen on {host}:{port}: "
                         f"{exc.strerror or exc}")
    return problems.lines


# ---------------------------------------------------------------------------- descriptors


def fds_needed(config: Config) -> int:
    """File descriptors the gateway may hold at once with this config."""
    workers = config.gateway.analysis_workers or max(1, (os.cpu_count() or 2) - 1)
    return (FDS_BASE + config.modbus_server.max_connections + config.metrics.max_connections
            + FDS_PER_DEVICE * len(config.devices) + FDS_PER_WORKER * workers)


def _check_fds(problems: Problems, config: Config) -> None:
    _soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    need = fds_needed(config)
    if hard == resource.RLIM_INFINITY or need <= hard:
        return
    problems.add("modbus_server", "max_connections",
                 f"the gateway may need {need:,} file descriptors ({FDS_BASE} + "
                 f"modbus_server.max_connections + metrics.max_connections + "
                 f"{FDS_PER_DEVICE} per device + {FDS_PER_WORKER} per analysis worker), over "
                 f"this process's limit of {hard:,} (LimitNOFILE): raise LimitNOFILE or "
                 "lower max_connections")


# ---------------------------------------------------------------------------- converters


def identification(value: Any) -> tuple[tuple[str, str], ...]:
    """``modbus_server.identification``: what read device identification answers."""
    if not isinstance(value, dict):
        raise TypeError("must be a mapping of identification objects")
    unknown = [str(k) for k in value if k not in IDENTIFICATION_OBJECTS]
    if unknown:
        raise ValueError(f"unknown object {unknown[0]!r} (known: "
                         f"{', '.join(IDENTIFICATION_OBJECTS)})")
    if not all(k in value for k in IDENTIFICATION_OBJECTS[:3]):
        raise ValueError("needs vendor_name, product_code and revision")
    for k, text in value.items():
        if not isinstance(text, str) or not text.isascii() or not text.isprintable() \
                or not 0 < len(text) <= MAX_IDENTIFICATION_CHARS:
            raise ValueError(f"{k} must be printable ASCII text of 1 to "
                             f"{MAX_IDENTIFICATION_CHARS} characters")
    return tuple((k, value[k]) for k in IDENTIFICATION_OBJECTS if k in value)
