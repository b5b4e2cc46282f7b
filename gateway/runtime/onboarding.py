"""The onboarding commands of ``stiction-gateway`` (docs/onboarding.md): ``import-tags``,
``probe``, ``browse`` and ``result-map``, and ``shard`` (docs/fleet.md): their arguments and
what they print.

:func:`add_commands` adds them to the CLI's parser; :func:`dispatch` runs one. Exit status
as the CLI's: 0 ok, 1 a device could not be read (or a point came back bad), 2 bad usage
or a bad config or tag list (every problem printed on stderr, one per line).
"""

from __future__ import annotations

import argparse
import asyncio
import sys
from pathlib import Path
from typing import Any

from ..config import load_config
from ..config.shard import describe, shard_tags
from ..config.tagimport import import_tags
from ..core.points import Quality
from ..errors import ConfigError, DeviceError
from ..outputs.modbus_server.resultmap import map_csv, map_rows, map_table
from .probe import format_probe, probe, select_loops

__all__ = ["COMMANDS", "add_commands", "dispatch"]

COMMANDS = ("import-tags", "probe", "browse", "result-map", "shard")


def add_commands(sub: Any) -> None:
    """Add the onboarding commands to ``sub`` (the CLI's ``add_subparsers()``)."""
    imp = sub.add_parser("import-tags", help="turn a tag list (CSV) into the config's loops "
                                             "(docs/configuration.md#tag-lists)")
    imp.add_argument("file", metavar="FILE.csv")
    imp.add_argument("--config", metavar="FILE", help="config with the devices: check the rows "
                     "against it and write it whole, with the rows as its loops")
    imp.add_argument("-o", "--output", metavar="OUT.yaml", help="write here (default: stdout)")
    prb = sub.add_parser("probe", help="read each loop's OP and PV once, as the gateway would")
    prb.add_argument("--config", required=True, metavar="FILE", help="gateway YAML config")
    prb.add_argument("loops", nargs="*", metavar="LOOP", help="only these loops")
    brw = sub.add_parser("browse", help="list the variables under an OPC UA node")
    brw.add_argument("endpoint", metavar="ENDPOINT",
                     help="opc.tcp://host:port, or a device name of --config")
    brw.add_argument("node", nargs="?", metavar="NODE", help="start node (default: Objects)")
    brw.add_argument("--config", metavar="FILE", help="take ENDPOINT's endpoint, timeout and "
                     "security from this config's device of that name")
    brw.add_argument("--depth", type=int, default=5, metavar="N", help="levels (default 5)")
    rmap = sub.add_parser("result-map", help="every loop's result registers, for SCADA")
    rmap.add_argument("--config", required=True, metavar="FILE", help="gateway YAML config")
    rmap.add_argument("--csv", action="store_true", help="CSV instead of a table")
    rmap.add_argument("loops", nargs="*", metavar="LOOP", help="only these loops")
    shd = sub.add_parser("shard", help="split a tag list over N gateways by PLC "
                                       "(docs/fleet.md)")
    shd.add_argument("file", metavar="FILE.csv")
    shd.add_argument("--gateways", type=int, required=True, metavar="N",
                     help="how many gateways (at most one per PLC)")
    shd.add_argument("--config", metavar="FILE", help="config with the devices: each "
                     "gateway's config is this one with its own devices")
    shd.add_argument("-o", "--output", metavar="DIR", default=".",
                     help="write NAME-1.yaml, NAME-1.csv, ... here (default: .)")
    shd.add_argument("--name", default="gateway", help="file name prefix (default: gateway)")


def dispatch(args: argparse.Namespace) -> int:
    if args.command == "import-tags":
        return _import_tags(args)
    if args.command == "probe":
        return _probe(args)
    if args.command == "browse":
        return _browse(args)
    if args.command == "result-map":
        config = load_config(args.config)
        select_loops(config, args.loops)  # ConfigError for an unknown loop
        rows = map_rows(config, args.loops)
        sys.stdout.write(map_csv(rows) if args.csv else map_table(rows))
        return 0
    if args.command == "shard":
        return _shard(args)
    raise AssertionError(args.command)


def _shard(args: argparse.Namespace) -> int:
    shards, idle = shard_tags(args.file, args.gateways, args.config, args.name)  # or raises
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    for s in shards:
        (out / s.yaml_name).write_text(s.yaml_text, encoding="utf-8")
        (out / s.csv_name).write_text(s.csv_text, encoding="utf-8")
    print("\n".join(describe(shards, args.file, idle)))
    return 0


def _import_tags(args: argparse.Namespace) -> int:
    result = import_tags(args.file, args.config)
    for line in result.problems:
        print(line, file=sys.stderr)
    if result.text is None:  # not only bad rows: nothing written
        return 2
    if args.output:
        Path(args.output).write_text(result.text, encoding="utf-8")
    else:
        sys.stdout.write(result.text)
    bad = result.bad_lines
    where = f"wrote {args.output}" if args.output else "written"
    print(f"{args.file}: {where}: {result.loops} loop(s)"
          + (f"; {len(bad)} bad row(s) left out (lines {', '.join(map(str, bad))})"
             if bad else ""), file=sys.stderr)
    return 2 if bad else 0


def _probe(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    results = asyncio.run(probe(config, args.loops))
    if any(d.rows for d in results):
        sys.stdout.write(format_probe(results))
    for dev in results:
        for err in ([dev.error] if dev.error is not None else list(dev.errors)):
            print(f"stiction-gateway: {err}", file=sys.stderr)
    good = sum(1 for d in results for r in d.rows if r.quality == Quality.GOOD)
    odd = sum(1 for d in results for r in d.rows if r.shown_quality == "IMPLAUSIBLE")
    points = sum(len(lp.points) for lp in select_loops(config, args.loops))
    print(f"{good} of {points} point(s) good"
          + (f", {odd} implausible (see status)" if odd else ""), file=sys.stderr)
    return 0 if all(d.ok for d in results) else 1


def _browse(args: argparse.Namespace) -> int:
    # asyncua is loaded only to browse
    from ..inputs.opcua.browse import browse, format_browse  # noqa: PLC0415
    from ..inputs.opcua.config import OpcUaDeviceConfig, parse_node_id  # noqa: PLC0415

    if args.config:
        devices = {d.name: d for d in load_config(args.config).devices}
        device = devices.get(args.endpoint)
        if device is None or device.protocol != "opcua":
            raise ConfigError([f"{args.config}: no OPC UA device {args.endpoint!r}"])
        cfg = OpcUaDeviceConfig(device.name, device.options.endpoint, device.poll_interval_s,
                                device.timeout_s, device.options.security)
    else:
        if not args.endpoint.startswith("opc.tcp://"):
            raise ConfigError([f"browse: {args.endpoint!r} is not an opc.tcp://host:port "
                               f"endpoint (or give --config with a device of that name)"])
        cfg = OpcUaDeviceConfig("", args.endpoint, 1.0, 2.0)
    if args.node is not None:
        try:
            parse_node_id(args.node)
        except (TypeError, ValueError) as exc:
            raise ConfigError([f"browse: node {args.node!r} {exc}"]) from None
    try:
        found = asyncio.run(browse(cfg, args.node, depth=args.depth))
    except DeviceError as exc:
        print(f"stiction-gateway: {exc}", file=sys.stderr)
        return 1
    sys.stdout.write(format_browse(found))
    print(f"{len(found)} variable(s)", file=sys.stderr)
    return 0
