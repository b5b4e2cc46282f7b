"""Everything built from one config, the carry-over from the previous one on reload, and
the steps of a reload that may refuse it.

A reload (:meth:`gateway.runtime.gateway.Gateway.reload`) is a transaction: it changes
nothing until every step that can fail has passed, in this order -

1. :func:`read_new_config`: read and decode the file within the limits of
   :mod:`gateway.config.limits`, parse and validate it (in a thread, so polls go on);
2. :func:`prepare_listeners`: every output whose listen address moved binds its new one;
3. :func:`build_runtime` (below; the pollers are stopped first, to copy the windows);

then the new listeners take over and the sinks are bound. Any failure raises
:class:`ReloadRefused`: one log line naming the file and the problem, one count in
``stiction_config_reload_failures_total{stage}``, and the running config untouched.

:func:`build_runtime` is a plain function (no sockets, no tasks): from a config (and, on a
reload, the old :class:`Runtime`, whose pollers have stopped) it builds the result store,
one source per device, the loop groups (windows) and one poller per device:

* a device whose connection and points are unchanged keeps its source (its connection) and
  its connection state (up/down, backoff);
* a loop whose *window signature* (device connection and sample time, OP/PV point
  definitions; its length aside: a shorter window keeps the newest samples) is unchanged
  keeps its window;
* a loop whose whole config is also unchanged keeps its latest assessment (same sequence
  number), latest sample and stale flag;
* added loops and loops whose window changed start fresh; removed loops are not carried.
"""

from __future__ import annotations

import asyncio
import dataclasses
import os
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ..config import parse_config
from ..config.limits import read_document
from ..config.model import Config, DeviceConfig, LoopConfig
from ..config.plugins import input_plugin
from ..core.points import PointSpec
from ..core.store import ResultStore
from ..core.ticks import Backoff, ProcessClock, TickGrid
from ..core.windows import LoopGroup, WindowBank, load_columns, loop_signature, result_signature
from ..errors import ConfigError
from ..inputs.base import Source
from ..outputs.base import Binding, Sink, Swap
from ..outputs.prometheus import GatewayMetrics
from .logs import clip
from .poller import BACKOFF_BASE_S, Clocks, DevicePoller

__all__ = ["LISTEN_SECTIONS", "MAX_PROBLEMS_LOGGED", "ReloadRefused", "Runtime",
           "build_runtime", "device_points", "prepare_listeners", "read_new_config",
           "reload_summary"]

SourceFactory = Callable[[DeviceConfig, list[PointSpec], float], Source]
LISTEN_SECTIONS = {"modbus_server": "modbus_server", "prometheus": "metrics"}
"""Output name -> the config section whose ``listen`` it binds."""
MAX_PROBLEMS_LOGGED = 10


class ReloadRefused(Exception):
    """A reload that did not happen: ``stage`` (read, validate, listen, build) and one line
    naming the file and the problem(s)."""

    def __init__(self, stage: str, line: str) -> None:
        super().__init__(line)
        self.stage = stage
        self.line = line


def _problems_line(problems: Sequence[str]) -> str:
    shown = "; ".join(problems[:MAX_PROBLEMS_LOGGED])
    more = len(problems) - MAX_PROBLEMS_LOGGED
    tail = f"; and {more} more (stiction-gateway check-config lists them)" if more > 0 else ""
    return f"{len(problems)} problem(s): {shown}{tail}"


def _unexpected(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {clip(exc, 200)}"


async def read_new_config(path: str | os.PathLike[str]) -> Config:
    """Steps read and validate of a reload (in a thread); ReloadRefused on any failure,
    even an unexpected one (a reload must never end the daemon)."""
    source = str(path)
    try:
        document = await asyncio.to_thread(read_document, path)
    except ConfigError as exc:
        raise ReloadRefused("read", _problems_line(exc.problems)) from None
    except Exception as exc:
        raise ReloadRefused("read", f"{source}: cannot be read: {_unexpected(exc)}") from None
    try:
        return await asyncio.to_thread(parse_config, document, source)
    except ConfigError as exc:
        raise ReloadRefused("validate", _problems_line(exc.problems)) from None
    except Exception as exc:
        raise ReloadRefused("validate", f"{source}: cannot be validated: "
                            f"{_unexpected(exc)}") from None


async def prepare_listeners(sinks: Mapping[str, Sink], config: Config) -> list[Swap]:
    """Step listen of a reload: every sink whose address moved binds its new one (not yet
    serving). On failure what was bound is closed again and ReloadRefused raised."""
    swaps: list[Swap] = []
    for name, sink in sinks.items():
        prepare = getattr(sink, "prepare", None)
        if prepare is None:
            continue
        try:
            swap = await prepare(config)
        except OSError as exc:
            for s in swaps:
                await s.abort()
            section = LISTEN_SECTIONS.get(name, name)
            host, port = getattr(config, section).listen
            reason = os.strerror(exc.errno) if exc.errno else str(exc)
            raise ReloadRefused("listen", f"{config.source}: {section}: key 'listen': cannot "
                                f"listen on {host}:{port}: {reason}") from None
        if swap is not None:
            swaps.append(swap)
    return swaps


@dataclasses.dataclass
class Runtime:
    """The store, sources, windows and pollers of one config."""

    config: Config
    clock: ProcessClock
    store: ResultStore
    pollers: list[DevicePoller]
    groups: list[LoopGroup]
    built_for: dict[str, tuple[DeviceConfig, list[PointSpec]]]  # what each source serves

    @property
    def sources(self) -> dict[str, Source]:
        return {p.device.name: p.source for p in self.pollers}

    def binding(self) -> Binding:
        return Binding(self.config, tuple(self.groups), self.store, self.clock)


def device_points(loops: Sequence[LoopConfig]) -> list[PointSpec]:
    """A device's point list: each loop's OP, PV and position (where it has one), in loop
    order (an OP's span is its loop's op_range, and a position's, in OP units: core.points
    judges them by that too)."""
    return [PointSpec(lp.name, role, p.address, p.scale, p.offset, p.range,
                      lp.op_range if role != "pv" else None, lp.origin)
            for lp in loops for role, p in lp.points]


def plugin_source(device: DeviceConfig, points: list[PointSpec], time_scale: float) -> Source:
    """The source the device's protocol plugin builds (no connection is opened)."""
    plugin = input_plugin(device.protocol)
    assert plugin is not None  # validated at load
    source: Source = plugin.create_input(device, points, time_scale=time_scale)
    return source


def build_runtime(config: Config, old: Runtime | None = None, *, wall: float,
                  metrics: GatewayMetrics | None = None, phase_ref: float | None = None,
                  clocks: Clocks | None = None,
                  make_source: SourceFactory = plugin_source) -> Runtime:
    """Build a runtime for ``config`` (see the module docstring); ``wall`` starts a new
    process clock."""
    g = config.gateway
    clock = (old.clock if old is not None and old.clock.time_scale == g.time_scale
             else ProcessClock(g.time_scale, start=wall))
    store = ResultStore([lp.name for lp in config.loops])
    old_cols: dict[str, tuple[WindowBank, int, str]] = {}
    if old is not None:
        for og in old.groups:
            for c, lc in enumerate(og.configs):
                old_cols[lc.name] = (og.bank, c, loop_signature(old.config, lc))
    pollers: list[DevicePoller] = []
    built_for: dict[str, tuple[DeviceConfig, list[PointSpec]]] = {}
    groups: list[LoopGroup] = []
    for dev in config.devices:
        loops = config.loops_of(dev.name)
        points = device_points(loops)
        built_for[dev.name] = (dev, points)
        old_poller = None
        if old is not None and old.built_for.get(dev.name) == (dev, points):
            old_poller = next(p for p in old.pollers if p.device.name == dev.name)
        source = (old_poller.source if old_poller is not None
                  else make_source(dev, points, g.time_scale))
        dev_groups = _groups(config, dev, loops, store)
        for grp in dev_groups:
            _carry_windows(config, grp, old_cols)
        groups.extend(dev_groups)
        poller = DevicePoller(dev, source, dev_groups, points, store=store, metrics=metrics,
                              clock=clock, clocks=clocks,
                              backoff=Backoff(min(BACKOFF_BASE_S, g.reconnect_max_s), 2.0,
                                              g.reconnect_max_s))
        poller.grid = TickGrid(poller.period, phase_ref)
        if old_poller is not None:
            poller.take_over(old_poller)
        pollers.append(poller)
    new = Runtime(config, clock, store, pollers, groups, built_for)
    if old is not None:
        _carry_results(old, new)
    return new


def _groups(config: Config, dev: DeviceConfig, loops: Sequence[LoopConfig],
            store: ResultStore) -> list[LoopGroup]:
    """A device's loops grouped by window length (one bank per length)."""
    by_size: dict[int, list[int]] = {}
    first: list[int] = []  # index of each loop's OP in the device's point list
    for k, lp in enumerate(loops):
        by_size.setdefault(config.window_samples(lp), []).append(k)
        first.append(first[-1] + len(loops[k - 1].points) if k else 0)
    out = []
    for size, members in by_size.items():
        ks = np.array([first[k] for k in members], dtype=np.intp)
        rows = np.array([store.index[loops[k].name] for k in members], dtype=np.intp)
        pos = np.array([first[k] + 2 if loops[k].position is not None else -1
                        for k in members], dtype=np.intp)
        has = bool((pos >= 0).any())
        out.append(LoopGroup(dev.name, WindowBank([loops[k].name for k in members], size,
                                                  position=has),
                             tuple(loops[k] for k in members), ks, ks + 1, rows,
                             dev.poll_interval_s, pos if has else None))
    return out


def _carry_windows(config: Config, group: LoopGroup,
                   old_cols: dict[str, tuple[WindowBank, int, str]]) -> None:
    """Copy into the group's fresh bank the old windows of loops whose signature held."""
    columns = {}
    t_best: Any = np.empty(0)
    for col, lc in enumerate(group.configs):
        hit = old_cols.get(lc.name)  # (its length aside: a shorter window keeps the newest)
        if hit is None or hit[2] != loop_signature(config, lc, samples=hit[0].size):
            continue
        old_bank, c, _sig = hit
        t, op, pv, q = old_bank.series([c])
        pos = old_bank.positions([c])
        columns[col] = (op[0], pv[0], q[0], None if pos is None else pos[0])
        if len(t) > len(t_best):
            t_best = t
    if columns:
        load_columns(group.bank, t_best, columns)


def _carry_results(old: Runtime, new: Runtime) -> None:
    """Latest assessment, sample and stale flag of every loop whose config is unchanged."""
    for name, i in new.store.index.items():
        j = old.store.index.get(name)
        if j is None:
            continue
        new.store.seq_floor[i] = old.store.last_seq(j)  # a changed loop numbers on
        lc_new, lc_old = new.config.loops[i], old.config.loops[j]
        if result_signature(new.config, lc_new) != result_signature(old.config, lc_old):
            continue
        res = old.store.results[j]
        if res is not None:
            new.store.restore_result(i, res)
        new.store.latest_op[i] = old.store.latest_op[j]
        new.store.latest_pv[i] = old.store.latest_pv[j]
        new.store.latest_position[i] = old.store.latest_position[j]
        new.store.position_quality[i] = old.store.position_quality[j]
        new.store.stale[i] = old.store.stale[j]
        new.store.down[i] = old.store.down[j]


def reload_summary(old: Runtime, new: Runtime) -> str:
    """``FILE: N devices, M loops (a added, r removed, k windows kept)`` for the log."""
    config = new.config
    old_loops, new_loops = set(old.store.index), set(new.store.index)
    kept = sum(1 for grp in new.groups for lc in grp.configs
               if lc.name in old_loops and grp.bank.count > 0)
    return (f"{config.source}: {len(config.devices)} devices, {len(config.loops)} loops "
            f"({len(new_loops - old_loops)} added, {len(old_loops - new_loops)} removed, "
            f"{kept} windows kept)")
