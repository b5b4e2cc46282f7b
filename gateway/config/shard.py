"""``stiction-gateway shard``: one tag list split over N gateways by PLC (docs/fleet.md).

The rows are checked first as a gateway reads ``loops_csv`` (:mod:`.tags`), against the
devices of a base config (``--config``) or, without one, devices guessed as ``import-tags``
guesses them: one problem anywhere and nothing is written. Then the devices are grouped
into PLCs: devices that share a network endpoint (Modbus host and port, the host and port
of an OPC UA endpoint) are one PLC, e.g. a Modbus TCP gateway answering for several unit
ids, so no PLC is polled by two gateways (guessed devices are one PLC each). The PLCs are
dealt out largest first, each to the gateway with the fewest loops so far (ties: the lower
number), so the gateways carry about as many loops each, whatever the order of the rows.

Gateway ``k`` (1..N) is the base config with only its devices (those that have loops), the
base's own ``loops`` of those devices, and ``loops_csv: NAME-k.csv``: the rows of its devices
in the order of the tag list. Each gateway assigns the result blocks of its loops itself, by
the rule of :mod:`.addresses` (a ``result_address`` cell is kept): the addresses listed here
are those its result server serves, and ``result-map --config NAME-k.yaml`` shows them.
"""

from __future__ import annotations

import csv
import dataclasses
import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import yaml

from ..errors import ConfigError
from .load import parse_config
from .model import Config, DeviceConfig
from .tagimport import guessed_devices, read_yaml
from .tags import TagTable, read_tag_file

__all__ = ["Shard", "describe", "plc_key", "shard_tags"]


@dataclasses.dataclass(frozen=True)
class Shard:
    """Gateway ``number`` of a split: its devices and PLCs, its config as the gateway
    loads it, and the two files to write (``yaml_name`` refers to ``csv_name``)."""

    number: int
    devices: tuple[str, ...]
    plcs: tuple[str, ...]
    config: Config
    yaml_name: str
    yaml_text: str
    csv_name: str
    csv_text: str

    @property
    def loops(self) -> int:
        return len(self.config.loops)


def plc_key(device: DeviceConfig) -> str:
    """The PLC a device reads: its network endpoint (``host:port``), else its name."""
    options = device.options
    host, port = getattr(options, "host", None), getattr(options, "port", None)
    if isinstance(host, str) and isinstance(port, int):
        return f"{host.lower()}:{port}"
    endpoint = getattr(options, "endpoint", None)
    if isinstance(endpoint, str):
        return urlsplit(endpoint).netloc.lower() or endpoint
    return device.name


def shard_tags(csv_path: str | Path, gateways: int, config: str | Path | None = None,
               name: str = "gateway") -> tuple[list[Shard], list[str]]:
    """Split the tag list ``csv_path`` over ``gateways`` gateways (see the module
    docstring): the shards, and the devices left out because no loop reads them. Raise
    ConfigError listing every problem (nothing is split then)."""
    table = read_tag_file(csv_path)
    if config is not None:
        source = str(config)
        data = read_yaml(config)
        if not isinstance(data, dict):
            parse_config(data, source)  # raises: what is wrong with it
        data.pop("loops_csv", None)  # the tag list named on the command line is the list
    else:
        source, data = str(csv_path), {"devices": guessed_devices(table)}
    # every row checked here; each gateway's own limits (result blocks, memory) per shard
    whole = parse_config({**data, "loops_csv": table}, source, one_gateway=False)
    counts: dict[str, int] = {}
    for lp in whole.loops:
        counts[lp.device] = counts.get(lp.device, 0) + 1
    plcs: dict[str, list[str]] = {}  # PLC -> its devices with loops, in config order
    for dev in whole.devices:
        if counts.get(dev.name):
            plcs.setdefault(plc_key(dev) if config is not None else dev.name,
                            []).append(dev.name)
    if gateways < 1 or gateways > len(plcs):
        raise ConfigError([f"{csv_path}: cannot split over {gateways} gateway(s): its loops "
                           f"are on {len(plcs)} PLC(s) ({', '.join(plcs)}), and a PLC is "
                           f"polled by one gateway"])
    dealt = _deal({p: sum(counts[d] for d in devs) for p, devs in plcs.items()}, gateways)
    out = []
    for k, mine in enumerate(dealt, start=1):
        devices = {d for p in mine for d in plcs[p]}
        out.append(_shard(k, name, data, table, source, devices=devices, plcs=mine))
    return out, [d.name for d in whole.devices if not counts.get(d.name)]


def _deal(loads: dict[str, int], n: int) -> list[list[str]]:
    """PLCs (in first-seen order) dealt to ``n`` gateways, largest first to the least
    loaded; each gateway's PLCs in first-seen order."""
    order = list(loads)
    bins: list[list[str]] = [[] for _ in range(n)]
    total = [0] * n
    for plc in sorted(order, key=lambda p: (-loads[p], order.index(p))):
        k = min(range(n), key=lambda i: (total[i], i))
        bins[k].append(plc)
        total[k] += loads[plc]
    return [sorted(b, key=order.index) for b in bins]


def _shard(k: int, name: str, data: dict[str, Any], table: TagTable, source: str, *,
           devices: set[str], plcs: Sequence[str]) -> Shard:
    rows = [r for r in table.rows if r.cells.get("device") in devices]
    csv_name = f"{name}-{k}.csv"
    sub = dict(data)
    sub["devices"] = [d for d in data.get("devices") or []
                      if isinstance(d, dict) and d.get("name") in devices]
    own = [lp for lp in data.get("loops") or []
           if isinstance(lp, dict) and lp.get("device") in devices]
    sub.pop("loops", None)
    if own:
        sub["loops"] = own
    config = parse_config({**sub, "loops_csv": TagTable(csv_name, rows)}, source)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(table.columns)
    writer.writerows([r.cells.get(c, "") for c in table.columns] for r in rows)
    names = ", ".join(d["name"] for d in sub["devices"])
    head = (f"# Gateway {k} of a tag list split by `stiction-gateway shard` ({table.source}):"
            f" devices {names}\n")
    yaml_text = head + yaml.safe_dump({**sub, "loops_csv": csv_name}, sort_keys=False,
                                      default_flow_style=None)
    return Shard(k, tuple(d["name"] for d in sub["devices"]), tuple(plcs), config,
                 f"{name}-{k}.yaml", yaml_text, csv_name, head + buf.getvalue())


def describe(shards: Sequence[Shard], source: str, idle: Sequence[str] = ()) -> list[str]:
    """What ``shard`` prints: per gateway its loops, devices and result blocks."""
    total = sum(s.loops for s in shards)
    lines = [f"{source}: {total} loop(s) on {sum(len(s.plcs) for s in shards)} PLC(s) over "
             f"{len(shards)} gateway(s):"]
    if idle:
        lines.append(f"  left out, no loop reads them: {', '.join(idle)}")
    for s in shards:
        blocks: dict[int, list[int]] = {}
        for lp in s.config.loops:
            blocks.setdefault(lp.result_unit_id or 0, []).append(lp.result_address)
        where = "; ".join(f"unit id {u} result_address {min(a)}..{max(a)}"
                          for u, a in sorted(blocks.items()))
        lines.append(f"  {s.yaml_name} ({s.csv_name}): {s.loops} loop(s), devices "
                     f"{', '.join(s.devices)} (PLC {', '.join(s.plcs)}); {where}")
    return lines
