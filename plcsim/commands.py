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
    sim.add_argument("--step-test", metavar="LOOP", help="hold LOOP in manual and play a "
                     "step test (the config's step_test section, or its defaults)")
    sim.add_argument("--record", metavar="FILE", help="with --step-test: write the test's "
                     "recording (t, op, pv, position) to FILE, for `stiction valve-test`")
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
    if args.step_test or args.record:
        sim_cfg = _with_step_test(sim_cfg, args.step_test, args.record)
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


def _with_step_test(cfg: Any, loop: str | None, record: str | None) -> Any:
    """The config with its step test set from --step-test / --record (ConfigError if the
    loop is not one of its single loops)."""
    import dataclasses

    from gateway.errors import ConfigError

    from .steptest import StepTest

    test = cfg.step_test or (StepTest(loop) if loop else None)
    if test is None:
        raise ConfigError(["--record needs --step-test LOOP (or a step_test section in "
                           "the config)"])
    if loop:
        test = dataclasses.replace(test, loop=loop)
    if test.loop not in {lp.name for lp in cfg.loops}:
        raise ConfigError([f"--step-test: no single loop {test.loop!r} (loops: "
                           f"{', '.join(lp.name for lp in cfg.loops)})"])
    if record:
        test = dataclasses.replace(test, record=Path(record))
    return dataclasses.replace(cfg, step_test=test)


def _demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    logging.getLogger().setLevel(logging.WARNING)  # the table is the output
    asyncio.run(run_demo(args.duration))
    return 0
