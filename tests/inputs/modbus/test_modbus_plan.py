"""Request planning: the fewest Modbus reads that cover a device's points."""

from __future__ import annotations

from gateway.inputs.modbus import ModbusPoint, plan_requests


def test_plan_merges_tables_gaps_and_splits_at_the_limit() -> None:
    pts = [ModbusPoint(a, "float32") for a in range(0, 400, 2)]
    reqs, first = plan_requests(pts, 125)
    assert [(r.address, r.count) for r in reqs] == [(0, 125), (125, 125), (250, 125), (375, 25)]
    assert first.tolist() == list(range(0, 400, 2))
    pts = [ModbusPoint(0, "float32"), ModbusPoint(10, "int16"), ModbusPoint(3, "uint16"),
           ModbusPoint(20, "int16", table="input"), ModbusPoint(6, "float64")]
    reqs, first = plan_requests(pts, 125, merge_gap=4)
    assert [(r.table, r.address, r.count) for r in reqs] == [("holding", 0, 11),
                                                              ("input", 20, 1)]
    assert first.tolist() == [0, 10, 3, 11, 6]
    reqs, _ = plan_requests(pts, 125, merge_gap=0)
    assert [(r.address, r.count) for r in reqs] == [(0, 2), (3, 1), (6, 5), (20, 1)]
