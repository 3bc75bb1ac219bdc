"""Fault specs: every kind parses; every bad part is named; the [[faults]] table
is validated like the other scenario fields (file, field path, reason)."""

from __future__ import annotations

import copy
import re

import pytest
from test_loader import BASE
from tlfleet.agent.model.faults import Fault, FaultSpecError, check_fault, parse_fault
from tlfleet.agent.scenario import parse_scenario
from tlfleet.bus.errors import ScenarioError


@pytest.mark.parametrize(("spec", "fault"), [
    ("cut:robot3@20+3", Fault("cut", ("agent-3",), 20.0, 3.0)),
    ("cut:sim@5.5+0.5", Fault("cut", ("sim",), 5.5, 0.5)),
    ("cut:router@1+2", Fault("cut", ("router",), 1.0, 2.0)),
    ("cut:host1@1+2", Fault("cut", ("host-1",), 1.0, 2.0)),
    ("partition:robot3,robot4@57+5", Fault("partition", ("agent-3", "agent-4"), 57.0, 5.0)),
    ("freeze:agent-2@1.5+3", Fault("freeze", ("agent-2",), 1.5, 3.0)),
    ("kill:robot2@2", Fault("kill", ("agent-2",), 2.0)),
    ("restart:robot12@0", Fault("restart", ("agent-12",), 0.0)),
    (" restart : agent2 @ .5 ", Fault("restart", ("agent-2",), 0.5)),
])
def test_every_kind_parses(spec, fault):
    parsed = parse_fault(spec)
    assert (parsed.kind, parsed.targets, parsed.at, parsed.duration) == \
        (fault.kind, fault.targets, fault.at, fault.duration)
    assert parsed.text == spec
    assert parse_fault(parsed.spec) == Fault(fault.kind, fault.targets, fault.at,
                                             fault.duration, parsed.spec)


def test_which_faults_need_namespace_hosts():
    assert parse_fault("cut:robot3@1+1").needs_hosts
    assert parse_fault("partition:robot3,sim@1+1").needs_hosts
    assert not any(parse_fault(s).needs_hosts
                   for s in ("freeze:robot3@1+1", "kill:robot3@1", "restart:sim@1"))


BAD = [
    ("robot3@20+3", "kind", "missing: expected KIND:TARGET@T"),
    ("drop:robot3@20+3", "kind", "'drop' is not a fault kind: expected one of cut, partition"),
    ("cut:robot3", "time", "missing: expected @T"),
    ("cut:@20+3", "target", "missing"),
    ("cut:robot@20+3", "target", "'robot' is not a target"),
    ("cut:robot-x@20+3", "target", "'robot-x' is not a target"),
    ("cut:robot3,robot4@20+3", "target", "cut takes one target, got 2"),
    ("partition:robot3@20+3", "target", "a partition needs two targets A,B, got 1"),
    ("partition:robot3,robot4,sim@20+3", "target", "a partition needs two targets A,B, got 3"),
    ("partition:robot3,agent-3@20+3", "target", "cannot be partitioned from itself"),
    ("partition:robot3,@20+3", "target", "missing"),
    ("freeze:host1@20+3", "target", "a host can only be cut or partitioned, not freeze"),
    ("cut:robot3@soon+3", "time", "'soon' is not a number of seconds"),
    ("cut:robot3@-1+3", "time", "'-1' is not a number of seconds"),
    ("cut:robot3@1e3+3", "time", "'1e3' is not a number of seconds"),
    ("cut:robot3@nan+3", "time", "'nan' is not a number"),
    ("cut:robot3@20", "duration", "cut needs \\+D"),
    ("freeze:robot3@20", "duration", "freeze needs \\+D"),
    ("cut:robot3@20+", "duration", "'' is not a number of seconds"),
    ("cut:robot3@20+x", "duration", "'x' is not a number of seconds"),
    ("cut:robot3@20+0", "duration", "0.0 s: expected a wall time > 0 s"),
    ("cut:robot3@20+4000", "duration", "4000 s: at most 3600 s"),
    ("kill:robot3@20+3", "duration", "kill takes no \\+D"),
    ("restart:robot3@20+3", "duration", "restart takes no \\+D"),
]


@pytest.mark.parametrize(("spec", "part", "message"), BAD)
def test_bad_specs_name_the_wrong_part(spec, part, message):
    with pytest.raises(FaultSpecError, match=message) as caught:
        parse_fault(spec)
    assert caught.value.part == part
    assert str(caught.value).startswith(f"fault {spec!r}: {part}: ")


def test_a_fault_is_checked_against_the_run():
    check_fault(parse_fault("cut:robot3@20+3"), [1, 2, 3], 90.0)
    with pytest.raises(FaultSpecError, match="no robot 7 \\(robots: 1, 2, 3\\)") as caught:
        check_fault(parse_fault("kill:robot7@20"), [3, 1, 2], 90.0)
    assert caught.value.part == "target"
    with pytest.raises(FaultSpecError, match="@90 s is not before the end of the run") as caught:
        check_fault(parse_fault("kill:robot1@90"), [1], 90.0)
    assert caught.value.part == "time"


def with_faults(*faults):
    data = copy.deepcopy(BASE)
    data["faults"] = list(faults)
    return data


def test_the_faults_table_loads_both_forms():
    scenario = parse_scenario(with_faults(
        {"spec": "freeze:robot2@1+3"},
        {"kind": "cut", "target": "robot1", "at": 2, "duration": 0.5},
        {"kind": "partition", "targets": ["robot1", "robot2"], "at": 3.0, "duration": 1},
        {"kind": "restart", "target": "sim", "at": 4}), "s.toml")
    assert [f.spec for f in scenario.faults] == [
        "freeze:agent-2@1+3", "cut:agent-1@2+0.5", "partition:agent-1,agent-2@3+1",
        "restart:sim@4"]
    assert parse_scenario(copy.deepcopy(BASE)).faults == ()


BAD_TABLES = [
    ({"spec": "freeze:robot2@1"}, "faults[0].spec", "duration of 'freeze:robot2@1': freeze "
                                                    "needs \\+D"),
    ({"spec": "kill:robot9@1"}, "faults[0].spec", "target of 'kill:robot9@1': agent-9: the "
                                                  "scenario has no robot 9"),
    ({"spec": 3}, "faults[0].spec", "expected a string, got integer 3"),
    ({"spec": "kill:robot1@1", "at": 2}, "faults[0].at", "unknown key 'at'"),
    ({"kind": "drop", "target": "robot1", "at": 1}, "faults[0].kind",
     "'drop' is not a fault kind"),
    ({"target": "robot1", "at": 1}, "faults[0].kind", "missing, expected a string"),
    ({"kind": "kill", "target": "robotx", "at": 1}, "faults[0].target", "'robotx' is not a "
                                                                        "target"),
    ({"kind": "kill", "target": "robot9", "at": 1}, "faults[0].target", "no robot 9"),
    ({"kind": "partition", "target": "robot1", "at": 1, "duration": 1}, "faults[0].target",
     "unknown key 'target' .*did you mean 'targets'"),
    ({"kind": "partition", "at": 1, "duration": 1}, "faults[0].targets",
     "missing, expected a list of strings"),
    ({"kind": "partition", "targets": ["robot1"], "at": 1, "duration": 1}, "faults[0].targets",
     "needs two targets"),
    ({"kind": "kill", "target": "robot1", "at": -1}, "faults[0].at", "expected a sim time ≥ 0"),
    ({"kind": "kill", "target": "robot1", "at": "1"}, "faults[0].at", "expected a number, got "
                                                                      "string"),
    ({"kind": "kill", "target": "robot1", "at": 10}, "faults[0].at", "not before the end of "
                                                                     "the run \\(10 s\\)"),
    ({"kind": "kill", "target": "robot1", "at": 1, "duration": 2}, "faults[0].duration",
     "kill takes no \\+D"),
    ({"kind": "cut", "target": "robot1", "at": 1}, "faults[0].duration", "cut needs \\+D"),
    ({"kind": "cut", "target": "robot1", "at": 1, "duration": -2}, "faults[0].duration",
     "expected a wall time > 0 s"),
    ({"kind": "cut", "target": "robot1", "at": 1, "duration": 2, "durtion": 3},
     "faults[0].durtion", "unknown key 'durtion'"),
]


@pytest.mark.parametrize(("table", "field", "message"), BAD_TABLES)
def test_bad_faults_tables_name_file_field_and_reason(table, field, message):
    with pytest.raises(ScenarioError, match=message) as caught:
        parse_scenario(with_faults({"kind": "kill", "target": "robot1", "at": 1}, table),
                       "s.toml")
    wanted = field.replace("faults[0]", "faults[1]")
    assert (caught.value.file, caught.value.field) == ("s.toml", wanted), str(caught.value)
    assert re.search(message, caught.value.reason)
