"""Shared helpers for the gateway tests: run coroutines, build configs around a plc-sim."""

from __future__ import annotations

import asyncio
import urllib.request
from collections.abc import Coroutine
from typing import Any, TypeVar

from gateway.config import Config, parse_config
from plcsim import SimConfig, gateway_config, parse_sim_config

T = TypeVar("T")


def run(coro: Coroutine[Any, Any, T], timeout: float = 120.0) -> T:
    """Run ``coro`` in a fresh event loop, bounded in time."""
    return asyncio.run(asyncio.wait_for(coro, timeout))


def sim_config(loops: list[dict[str, Any]], **top: Any) -> SimConfig:
    return parse_sim_config({"listen": "127.0.0.1:0", **top, "loops": loops}, "<test sim>")


def gateway_for(sim: SimConfig, port: int, *, device: dict[str, Any] | None = None,
                **gateway: Any) -> Config:
    """The gateway config for ``sim`` served on ``port``; servers on free loopback ports."""
    raw = gateway_config(sim, port=port, metrics_listen="127.0.0.1:0",
                         result_listen="127.0.0.1:0")
    raw["gateway"].update(gateway)
    raw["devices"][0].update(device or {})
    return parse_config(raw, "<test gateway>")


def scrape(port: int) -> str:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=5) as rsp:
        return str(rsp.read().decode())
