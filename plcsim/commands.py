"""The simulator's commands of ``stiction-gateway``: ``plc-sim`` and ``demo``.

Registered through the entry-point group ``stiction_gateway.commands`` (pyproject.toml), so
the gateway's CLI finds them by name and never imports this package: each function adds
its subcommand and the handler the CLI calls. The simulator itself is imported only when
one of them runs.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
from pathlib import Path
from typing import Any

__all__ = ["add_demo", "add_plc_sim"]


def add_plc_sim(sub: Any) -> None:
    sim = sub.add_parser("plc-sim", help="simulated PLC serving OP/PV over Modbus TCP")
    sim.add_argument("--config", required=True, metavar="FILE", help="plc-sim YAML config")
    sim.add_argument("--write-gateway-config", metavar="FILE",
                     help="write the matching gateway config to FILE and exit")
    sim.set_defaults(plugin=_plc_sim)


def add_demo(sub: Any) -> None:
    demo = sub.add_parser("demo", help="simulated PLC + gateway with a live verdict table")
    demo.add_argument("--duration", type=float, default=None, metavar="S",
                      help="stop after S wall seconds (default: run until Ctrl-C)")
    demo.set_defaults(plugin=_demo)


def _plc_sim(args: argparse.Namespace) -> int:
    from gateway.runtime.service import install_stop_signals

    from .config import load_sim_config
    from .gateway_yaml import dump_yaml, gateway_config
    from .sim import serve

    sim_cfg = load_sim_config(args.config)
    if args.write_gateway_config:
        text = dump_yaml(gateway_config(sim_cfg))
        Path(args.write_gateway_config).write_text(
            "# Gateway config for the simulated PLC of " + args.config + "\n" + text,
            encoding="utf-8")
        print(f"wrote {args.write_gateway_config}")
        return 0

    async def serve_sim() -> None:
        stop = asyncio.Event()
        install_stop_signals(stop)
        await serve(sim_cfg, stop)

    asyncio.run(serve_sim())
    return 0


def _demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    logging.getLogger().setLevel(logging.WARNING)  # the table is the output
    asyncio.run(run_demo(args.duration))
    return 0
