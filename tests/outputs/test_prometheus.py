"""The Prometheus output: per-loop series read from the store, the gateway's own series,
and the exposition linted by promtool."""

from __future__ import annotations

import asyncio
import dataclasses
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from prometheus_client import CollectorRegistry, generate_latest
from result_fixtures import sample_store

from gateway.config import parse_config
from gateway.core.plantview import PlantGroup, PlantView
from gateway.core.store import ResultStore
from gateway.outputs.base import Binding
from gateway.outputs.prometheus import GatewayMetrics, PrometheusSink, StoreCollector
from gateway.outputs.prometheus.plant import PlantCollector
from gateway.wire.listener import ListenerStats
from gateway.wire.results import result_block, verdict_code
from stiction import Assessment, Verdict

PLANT = PlantView((PlantGroup(1, 228.0, "FIC101", ("FIC101", "FIC401")),
                   PlantGroup(3, 600.0, None, ("TIC301", "FIC401"))),
                  {"FIC101": (1, "source"), "FIC401": (1, "follower"),
                   "TIC301": (3, "follower")})


def _registry() -> CollectorRegistry:
    registry = CollectorRegistry()
    store = sample_store()
    store.set_plant(PLANT)
    registry.register(StoreCollector(store))
    registry.register(PlantCollector(lambda: store))
    metrics = GatewayMetrics(registry)
    metrics.add_device("plc1")
    metrics.device_up.labels(device="plc1").set(1)
    metrics.poll_duration.labels(device="plc1").observe(0.004)
    metrics.poll_requests.labels(device="plc1").inc(4)
    metrics.poll_errors.labels(device="plc1", kind="timeout").inc()
    metrics.analysis_duration.observe(0.003)
    metrics.missed_ticks.labels(device="plc1").inc(2)
    metrics.poll_lateness.labels(device="plc1").observe(0.02)
    metrics.state_write_failures.inc()
    metrics.state_last_write.set(1_700_000_000)
    metrics.track_server("modbus", ListenerStats())
    metrics.add_device("plc2")  # down: a wrong unit id
    metrics.set_down_reason("plc2", "unit id 5 not served")
    metrics.count_refused("plc2", "unit id 5 not served")
    return registry


def test_a_down_device_has_one_reason_series_in_the_log_words_and_none_while_up() -> None:
    """Issue 23 item 1: why a device is down is a label (few values: the log's words);
    one series per device at a time, none while it is up or after it left the config."""
    reg = CollectorRegistry()
    m = GatewayMetrics(reg)
    m.add_device("plc1")

    def reasons() -> dict[str, float]:
        return {s.labels["reason"]: s.value for f in reg.collect()
                if f.name == "stiction_device_down_reason" for s in f.samples}

    assert reasons() == {}
    m.set_down_reason("plc1", "no connection")
    m.set_down_reason("plc1", "unit id 5 not served")
    assert reasons() == {"unit id 5 not served": 1.0}
    m.set_down_reason("plc1", None)
    assert reasons() == {}
    m.set_down_reason("plc1", "no answer")
    m.count_refused("plc1", "illegal data address")
    m.remove_device("plc1")
    assert reasons() == {}
    assert reg.get_sample_value("stiction_poll_refused_requests_total",
                                {"device": "plc1", "exception": "illegal data address"}) is None


def test_a_stale_loop_of_a_down_device_is_device_down_in_metrics_and_registers() -> None:
    st = ResultStore(["FIC101", "LIC201"])
    rows = np.array([0, 1])
    st.set_stale(rows, np.array([True, True]), down=True)
    st.set_stale(rows[1:], np.array([True]), down=False)
    reg = CollectorRegistry()
    reg.register(StoreCollector(st))
    got = {(lp, v): reg.get_sample_value("stiction_loop_verdict", {"loop": lp, "verdict": v})
           for lp in st.loops for v in ("device_down", "stale")}
    assert got == {("FIC101", "device_down"): 1.0, ("FIC101", "stale"): 0.0,
                   ("LIC201", "device_down"): 0.0, ("LIC201", "stale"): 1.0}
    assert verdict_code(None, stale=True, down=True) == 9
    doc = (Path(__file__).resolve().parents[2] / "docs" / "modbus-map.md").read_text()
    assert "| 9 | device down |" in doc


def test_a_window_warming_up_is_its_own_verdict_in_metrics_and_registers() -> None:
    """Issue 23 item 4: `warming_up` is a verdict series (one-hot with the others) and
    register code 8, as docs/modbus-map.md says."""
    st = ResultStore(["LIC201"])
    st.set_result(0, Assessment(Verdict.WARMING_UP, "warming up: ..."), t=1.7e9,
                  window_fill=0.08, samples=600)
    reg = CollectorRegistry()
    reg.register(StoreCollector(st))
    got = {v: reg.get_sample_value("stiction_loop_verdict", {"loop": "LIC201", "verdict": v})
           for v in ("warming_up", "not_oscillating", "none")}
    assert got == {"warming_up": 1.0, "not_oscillating": 0.0, "none": 0.0}
    assert verdict_code(st.results[0]) == 8 == result_block(st.results[0], code=8)[0]
    doc = (Path(__file__).resolve().parents[2] / "docs" / "modbus-map.md").read_text()
    assert "| 8 | warming up |" in doc


def test_metrics_read_the_store() -> None:
    reg = _registry()

    def v(name: str, **labels: str) -> float | None:
        return reg.get_sample_value(name, labels)

    assert v("stiction_loop_stiction_index", loop="FIC101") == pytest.approx(0.93)
    assert v("stiction_loop_fd_ratio", loop="FIC101") == pytest.approx(0.27)
    assert v("stiction_loop_fs_ratio", loop="FIC101") == pytest.approx(0.30)
    assert v("stiction_loop_jump_ratio", loop="FIC101") == pytest.approx(0.03)
    assert v("stiction_loop_oscillation_period_seconds", loop="FIC101") == 228.0
    assert v("stiction_loop_last_assessment_timestamp_seconds", loop="FIC101") == 1_700_000_300
    assert v("stiction_loop_window_fill_ratio", loop="FIC101") == 0.5
    assert v("stiction_loop_confidence_ratio", loop="FIC101") == pytest.approx(0.91)
    assert v("stiction_loop_confidence_ratio", loop="FIC401") is None  # none given
    assert v("stiction_loop_op_percent", loop="FIC101") == 51.5
    assert v("stiction_loop_pv", loop="FIC101") == pytest.approx(50.2)
    assert v("stiction_loop_verdict", loop="FIC101", verdict="stiction") == 1.0
    assert v("stiction_loop_verdict", loop="FIC101", verdict="no_stiction") == 0.0
    assert v("stiction_loop_verdict", loop="TIC301", verdict="none") == 1.0
    assert v("stiction_loop_fs_ratio", loop="FIC401") is None  # not estimated: no series
    assert v("stiction_loop_op_percent", loop="TIC301") is None
    assert v("stiction_device_up", device="plc1") == 1.0
    assert v("stiction_poll_requests_total", device="plc1") == 4.0
    assert v("stiction_poll_errors_total", device="plc1", kind="timeout") == 1.0
    assert v("stiction_poll_errors_total", device="plc1", kind="connect") == 0.0
    assert v("stiction_poll_duration_seconds_count", device="plc1") == 1.0
    assert v("stiction_analysis_duration_seconds_count") == 1.0
    assert v("stiction_build_info", version="0.1.0") == 1.0
    # the plant view: per loop its group and role, per group its period, source and size
    assert v("stiction_loop_plant_group", loop="FIC401") == 1.0
    assert v("stiction_loop_plant_role", loop="FIC101", role="source") == 1.0
    assert v("stiction_loop_plant_role", loop="FIC401", role="source") == 0.0
    assert v("stiction_loop_plant_role", loop="FIC401", role="follower") == 1.0
    assert v("stiction_plant_group_period_seconds", group="1", source="FIC101") == 228.0
    assert v("stiction_plant_group_loops", group="1", source="FIC101") == 2.0
    assert v("stiction_plant_group_period_seconds", group="3", source="") == 600.0
    text = generate_latest(reg).decode()
    assert "_created" not in text


def test_promtool_check_metrics() -> None:
    promtool = shutil.which("promtool")
    if promtool is None:
        if os.environ.get("CI") == "true":
            pytest.fail("promtool is missing under CI=true (.ci/run installs the prometheus "
                        "package)")
        pytest.skip("promtool not installed (Debian package prometheus); CI runs this")
    text = generate_latest(_registry())
    res = subprocess.run([promtool, "check", "metrics"], input=text, capture_output=True,
                         timeout=30, check=False)
    problems = (res.stdout + res.stderr).decode().strip()
    assert res.returncode == 0, problems
    assert problems == ""


def test_build_info_names_the_site_and_area_of_the_config() -> None:
    """gateway.site and gateway.area (docs/fleet.md) label stiction_build_info, and follow a
    reload; unset ones are no labels at all (not empty ones)."""
    base = {"devices": [{"name": "plc1", "protocol": "modbus", "host": "127.0.0.1"}],
            "loops": [{"name": "FIC101", "device": "plc1", "op": {"address": 0,
                       "type": "float32"}, "pv": {"address": 2, "type": "float32"}}]}
    plain = parse_config(base)
    north = parse_config({**base, "gateway": {"site": "plant-north", "area": "unit.3"}})
    south = parse_config({**base, "gateway": {"site": "plant_south"}})
    assert (north.gateway.site, north.gateway.area) == ("plant-north", "unit.3")
    assert (plain.gateway.site, plain.gateway.area) == (None, None)
    reg = CollectorRegistry()
    sink = PrometheusSink(reg, GatewayMetrics(reg), serve_http=False)
    store = ResultStore(["FIC101"])

    def info(config: object) -> dict[str, str]:
        binding = Binding(config, (), store, None)  # type: ignore[arg-type]
        asyncio.run(sink.bind(binding))
        (sample,) = [s for m in reg.collect() if m.name == "stiction_build" for s in m.samples]
        assert sample.value == 1.0
        return dict(sample.labels)

    assert info(plain) == {"version": "0.1.0"}
    assert info(north) == {"version": "0.1.0", "site": "plant-north", "area": "unit.3"}
    assert info(south) == {"version": "0.1.0", "site": "plant_south"}  # area gone
    assert dataclasses.replace(south.gateway, site=None) == plain.gateway


@pytest.mark.parametrize("accept", [
    "", "application/openmetrics-text; version=1.0.0; charset=utf-8",
    "text/plain; version=1.0.0; escaping=allow-utf-8",
    "application/openmetrics-text; version=1.0.0; escaping=dots"])
def test_the_fast_page_is_the_client_librarys_page(accept: str) -> None:
    """StoreCollector.page renders the per-loop series itself (3-5 times faster: the
    rendering thread holds the interpreter the pollers share) and must write exactly what
    prometheus_client writes, in both formats, odd loop names, missing and odd values
    included (an escaping that renames legacy names falls back to the client's encoder)."""
    from prometheus_client.exposition import choose_encoder  # noqa: PLC0415

    names = ["FIC101", 'say "hi"', "back\\slash", "new\nline", "Ünïcode-µ", "plain"]
    store = ResultStore(names)
    sticky = sample_store().results[0]
    assert sticky is not None
    for i in range(4):
        store.set_result(i, sticky.assessment, t=1_700_000_000.25 + i, window_fill=0.5,
                         samples=10)
    store.latest_op[:] = [51.5, -0.0, 1e-7, 123456789.0, np.nan, 0.0]
    store.latest_pv[:] = [1e300, -2.5, 0.1, np.inf, 7.0, 3.0]
    store.stale[1] = True
    registry = CollectorRegistry()
    GatewayMetrics(registry).add_device("plc1")
    collector = StoreCollector(store)
    registry.register(collector)
    encoder, ctype = choose_encoder(accept)
    fast = collector.page(registry, encoder, ctype.startswith("application/openmetrics"))
    assert fast == encoder(registry)
    assert b'loop="say \\"hi\\""' in fast and b'loop="new\\nline"' in fast
