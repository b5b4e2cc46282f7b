"""Register +19 (a plant group's source loop, by its place in the config) after loops are
removed or reordered (issue 38 item 13). On 5c94178 it silently named another loop for a
SCADA table made before. Now it is detectable: a reload, and a restart (the state file keeps
the order), log one WARNING naming the loops that moved; and it is stable where SCADA reads
the extended block (``modbus_server.block_registers: 32``): +23/+24 name the source loop's
block (unit id, address), which no reordering moves."""

from __future__ import annotations

import asyncio
import logging
from typing import Any

import pytest
from memory_harness import Harness, mconfig, mloop

from gateway.config import parse_config
from gateway.core.plantview import PlantGroup, PlantView
from gateway.inputs.memory import memory_device
from gateway.outputs.statefile import StateFile
from gateway.wire.results import decode_block


def _raw(tmp_path: Any, names: list[str], extended: bool = True) -> dict[str, Any]:
    addresses = {"FIC101": 0, "LIC201": 32, "TIC301": 64}  # pinned: each keeps its block
    raw = mconfig([memory_device("plc", [[50.0, 20.0]], poll_interval_s=0.05, repeat=True)],
                  [mloop(n, "plc", 0, addresses[n]) for n in names],
                  state_file=str(tmp_path / "gw.state"))
    if extended:
        raw["modbus_server"]["block_registers"] = 32
    return raw


def _group(h: Harness) -> None:
    """TIC301 drives a cycle that FIC101 follows."""
    h.store.set_plant(PlantView((PlantGroup(1, 300.0, "TIC301", ("TIC301", "FIC101")),),
                                {"TIC301": (1, "source"), "FIC101": (1, "follower")}))


def test_the_source_is_named_by_its_block_and_a_reorder_is_said(
        tmp_path: Any, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="gateway")
    before = Harness(parse_config(_raw(tmp_path, ["FIC101", "LIC201", "TIC301"]), "gw.yaml"))
    _group(before)
    block = decode_block(before.registers()[0:32])  # FIC101's
    assert (block["plant_source"], block["source_unit_id"], block["source_address"]) == \
        (3, 1, 64)
    lic = decode_block(before.registers()[32:64])
    assert (lic["plant_source"], lic["source_address"]) == (0, 65535)
    asyncio.run(StateFile(before.runtime.binding(), wall=lambda: before.time.wall).save(
        final=True))
    # LIC201 removed, TIC301 moved up: +19 counts TIC301 as 2 now, +23/+24 did not move
    raw = _raw(tmp_path, ["TIC301", "FIC101"])
    after = Harness(parse_config(raw, "gw.yaml"), old=before)
    _group(after)
    block = decode_block(after.registers()[0:32])
    assert (block["plant_source"], block["source_unit_id"], block["source_address"]) == \
        (1, 1, 64)
    # a restart with the new order says so (the state file kept the old one)
    again = Harness(parse_config(raw, "gw.yaml"), time=after.time)
    asyncio.run(StateFile(again.runtime.binding(), wall=lambda: again.time.wall).start())
    warned = [r.getMessage() for r in caplog.records if "register +19" in r.getMessage()]
    assert len(warned) == 1 and "2 loop(s) moved in the config's order (TIC301 3 -> 1, " \
        "FIC101 1 -> 2)" in warned[0]


def test_a_reload_that_reorders_loops_says_so(tmp_path: Any,
                                              caplog: pytest.LogCaptureFixture) -> None:
    from concurrent.futures import ThreadPoolExecutor  # noqa: PLC0415

    from prometheus_client import CollectorRegistry  # noqa: PLC0415

    from gateway.runtime.gateway import Gateway  # noqa: PLC0415

    caplog.set_level(logging.INFO, logger="gateway")

    async def go() -> None:
        cfg = parse_config(_raw(tmp_path, ["FIC101", "LIC201", "TIC301"], False), "gw.yaml")
        async with Gateway(cfg, registry=CollectorRegistry(), serve_http=False,
                           executor=lambda: ThreadPoolExecutor(1)) as gw:
            for _ in range(2):  # (the default block: the warning is for every site)
                assert await gw.reload(parse_config(
                    _raw(tmp_path, ["FIC101", "TIC301", "LIC201"], False), "gw.yaml"))

    asyncio.run(asyncio.wait_for(go(), 60))
    warned = [r.getMessage() for r in caplog.records if "register +19" in r.getMessage()]
    assert len(warned) == 1  # the second reload moved nothing
    assert warned[0].startswith("reload: 2 loop(s) moved in the config's order (TIC301 3 -> 2,"
                                " LIC201 2 -> 3)")
