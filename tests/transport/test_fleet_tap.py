"""``tlfleet echo/topics/hz``'s pieces without a fleet (tlfleet.cli.fleet_tap): key names, the
publisher read from the key layout, a sample as a JSON line (decoded by the one codec), rates."""

from __future__ import annotations

import argparse
import json
import math

import pytest
from tlfleet.bus.protocol import keys
from tlfleet.bus.protocol.codec import encode
from tlfleet.bus.protocol.messages import Command, Event, MocapFrame
from tlfleet.cli.fleet_tap import Rates, TapError, key_expression, sample_line, where


@pytest.mark.parametrize("name, expr", [
    ("mocap", "tlfleet/lab/mocap"), ("robot/*/cmd", "tlfleet/lab/robot/*/cmd"),
    ("**", "tlfleet/lab/**"), ("/event/", "tlfleet/lab/event"),
    ("tlfleet/other/mocap", "tlfleet/other/mocap"), ("tlfleet", "tlfleet"),
])
def test_key_expression(name: str, expr: str) -> None:
    assert key_expression("lab", name) == expr


def test_an_empty_key_is_an_error() -> None:
    with pytest.raises(TapError, match="empty"):
        key_expression("lab", " / ")


def test_publisher_of_follows_the_key_functions() -> None:
    fleet = "f1"
    table = {keys.clock(fleet): "sim", keys.mocap(fleet): "sim",
             keys.mocap_every(fleet, 20, 3): "sim", keys.mocap_at(fleet, 2): "sim",
             keys.sim_backfill(fleet): "sim", keys.cmd(fleet, 4): "robot4",
             keys.status(fleet, 12): "robot12", keys.collab(fleet, 3): "robot3",
             keys.control(fleet): "coordinator", keys.event(fleet, "sim", 0): "sim",
             keys.event(fleet, "agent", 3): "robot3",
             keys.event(fleet, "coordinator", 0): "coordinator",
             keys.alive(fleet, "agent", 3): "agent 3", keys.alive(fleet, "sim", 0): "sim 0",
             "other/thing": "?", "tlfleet/f1/unknown": "?"}
    for key, who in table.items():
        assert keys.publisher_of(key) == who, key


def test_sample_line_decodes_every_kind() -> None:
    frame = MocapFrame(t=1.5, seq=150, poses=((1, 0.5, -0.25, 3.0),), due=(1,))
    line = sample_line("tlfleet/f/mocap", encode(frame), 1000.0)
    assert line == {"key": "tlfleet/f/mocap", "received": 1000.0, "from": "sim",
                    "kind": "MocapFrame", "msg": {"t": 1.5, "seq": 150,
                                                  "poses": [[1, 0.5, -0.25, 3.0]], "due": [1]}}
    json.dumps(line)  # JSON-ready
    command = Command(robot=2, t=0.3, seq=30, u=(0.1, -0.2, 0.0))
    line = sample_line(keys.cmd("f", 2), encode(command), 1.0)
    assert line["kind"] == "Command" and line["from"] == "robot2"
    assert line["msg"]["u"] == [0.1, -0.2, 0.0]
    event = Event(t=2.0, source="agent/3", kind="repair", data={"stage": 2, "x": math.inf})
    line = sample_line(keys.event("f", "agent", 3), encode(event), 1.0)
    assert line["from"] == "robot3"  # an event key names its publisher
    assert line["msg"]["data"] == {"stage": 2, "x": "inf"}
    json.dumps(line)


@pytest.mark.parametrize("payload", [b"", b"\x00\x01garbage", b"\x81\xa1k\xa3Foo"])
def test_a_payload_that_is_no_message_is_shown_not_dropped(payload: bytes) -> None:
    line = sample_line("tlfleet/f/mocap", payload, 1.0)
    assert line["kind"] is None and line["bytes"] == len(payload) and line["error"]


def test_rates_over_a_window() -> None:
    now = [0.0]
    rates = Rates(window=1.0, clock=lambda: now[0])
    for k in range(21):  # 20 Hz for 1 s
        now[0] = 0.05 * k
        rates.add("a", "Clock")
    now[0] = 1.0
    rates.add("b")
    row = rates.snapshot()["a"]
    assert row["hz"] == pytest.approx(20.0) and row["count"] == 21
    assert row["max_gap"] == pytest.approx(0.05)
    assert rates.snapshot()["b"]["hz"] == 0.0  # one sample: no rate yet
    now[0] = 1.6  # the first 0.6 s of samples left the window
    row = rates.snapshot()["a"]
    assert row["count"] == 21 and row["hz"] == pytest.approx(20.0)
    now[0] = 10.0
    assert rates.snapshot()["a"]["hz"] == 0.0


def test_where_reads_the_run_json(tmp_path) -> None:
    (tmp_path / "run.json").write_text(json.dumps({"scenario": "s1", "fleet": "lab",
                                                   "endpoint": "tcp/127.0.0.1:4000"}))
    args = argparse.Namespace(run=tmp_path, fleet=None, connect=[])
    assert where(args) == ("lab", ("tcp/127.0.0.1:4000",))
    args = argparse.Namespace(run=tmp_path, fleet="x", connect=["tcp/127.0.0.1:1"])
    assert where(args) == ("x", ("tcp/127.0.0.1:1",))  # the flags win
    args = argparse.Namespace(run=None, fleet=None, connect=[])
    assert where(args) == ("*", ("tcp/127.0.0.1:7447",))
    args = argparse.Namespace(run=tmp_path / "nope", fleet=None, connect=[])
    with pytest.raises(TapError, match=r"run\.json"):
        where(args)
