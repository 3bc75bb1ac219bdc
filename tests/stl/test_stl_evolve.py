"""``tlfleet.agent.evolve.evolve`` against ``dataclasses.replace`` (per-tick agent
states)."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from tlfleet.agent.evolve import evolve
from tlfleet.agent.nav.executor import ExecutorState
from tlfleet.agent.policy.ltl import LtlState
from tlfleet.agent.policy.stl import AgentState
from tlfleet.agent.stl.funnel import Funnel, FunnelParams

NAMES = st.sampled_from(["a", "b", "c"])
CHANGES = st.fixed_dictionaries({}, optional={
    "step": st.integers(0, 50),
    "mode": st.sampled_from(["navigate", "hold", "rotate"]),
    "mode_since": st.floats(allow_nan=False),
    "visits": st.lists(st.tuples(NAMES, st.integers(0, 9)), max_size=3).map(tuple),
    "last_region": st.none() | NAMES,
    "command": st.tuples(st.floats(-1, 1), st.floats(-1, 1)),
    "remaining": st.floats(0, 10),
    "cycle_start": st.none() | st.floats(0, 100),
    "prev_time": st.none() | st.floats(0, 100),
})


def as_fields(state) -> dict:
    return {f.name: getattr(state, f.name) for f in dataclasses.fields(state)}


@given(CHANGES, CHANGES)
def test_evolve_equals_replace_on_the_executor_state(first, second):
    base = ExecutorState(prefix=("a", "b"), suffix=("c",), prev_others=np.zeros((2, 4)))
    via_replace = dataclasses.replace(dataclasses.replace(base, **first), **second)
    via_evolve = evolve(evolve(base, **first), **second)
    assert type(via_evolve) is ExecutorState
    assert as_fields(via_evolve).keys() == as_fields(via_replace).keys()
    for name, value in as_fields(via_replace).items():
        assert getattr(via_evolve, name) is value or getattr(via_evolve, name) == value, name
    assert as_fields(base) == as_fields(ExecutorState(prefix=("a", "b"), suffix=("c",),
                                                      prev_others=base.prev_others))  # untouched
    assert via_evolve.target == via_replace.target and via_evolve.rounds == via_replace.rounds


def test_evolve_keeps_the_instance_frozen_and_checks_names():
    state = evolve(ExecutorState(prefix=("a",), suffix=()), step=3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        state.step = 4
    with pytest.raises(TypeError, match=r"ExecutorState has no field \['stpe'\]"):
        evolve(state, stpe=1)
    assert evolve(state) is not state and as_fields(evolve(state)) == as_fields(state)


def test_evolve_refuses_classes_whose_init_does_more_than_assign():
    @dataclasses.dataclass(frozen=True)
    class Checked:
        x: int

        def __post_init__(self):
            assert self.x >= 0

    @dataclasses.dataclass(frozen=True)
    class Derived:
        x: int
        y: int = dataclasses.field(init=False, default=0)

    @dataclasses.dataclass(frozen=True)
    class Cached:
        x: int

        @functools.cached_property
        def double(self) -> int:
            return 2 * self.x

    @dataclasses.dataclass
    class Mutable:
        x: int

    for cls in (Checked, Derived, Cached, Mutable):
        with pytest.raises(TypeError, match=cls.__name__):
            evolve(cls(1), x=2)


def test_the_ltl_state_is_evolvable():
    fields = {f.name for f in dataclasses.fields(LtlState)}
    assert {"executor", "stepped", "pending_plan"} <= fields
    state = LtlState(executor=ExecutorState(prefix=("a",), suffix=()), buchi_states=frozenset(),
                     plan=None)
    assert evolve(state, stepped=True).stepped is True and state.stepped is False


FUNNEL = Funnel.init("G", 0.0, 10.0, 0.5, 0.2, 0.0, FunnelParams())
STL_CHANGES = st.fixed_dictionaries({}, optional={
    "k": st.integers(0, 5),
    "active": st.booleans(),
    "funnel": st.none() | st.just(FUNNEL),
    "ce": st.integers(0, 9),
    "c": st.integers(-1, 4),
    "events": st.tuples(st.integers(0, 3), st.integers(0, 3), st.integers(0, 3)),
    "follow": st.none() | st.integers(0, 4),
    "peers": st.dictionaries(st.integers(0, 4), st.none(), max_size=2),
    "rho_phi": st.floats(allow_nan=True),
    "t_done": st.floats(allow_nan=False),
    "announced": st.none() | st.tuples(st.integers(-1, 4), st.integers(0, 5), st.booleans()),
    "orphaned": st.none() | st.tuples(st.integers(0, 4), st.integers(0, 5)),
})


@given(STL_CHANGES, STL_CHANGES)
def test_evolve_equals_replace_on_the_slotted_stl_state(first, second):
    base = AgentState(k=1, active=True, funnel=FUNNEL, rho_phi=0.25)
    via_replace = dataclasses.replace(dataclasses.replace(base, **first), **second)
    via_evolve = evolve(evolve(base, **first), **second)
    assert type(via_evolve) is AgentState and not hasattr(via_evolve, "__dict__")
    for f in dataclasses.fields(AgentState):  # every slot set, to the very object replace sets
        assert getattr(via_evolve, f.name) is getattr(via_replace, f.name), f.name
    assert base == AgentState(k=1, active=True, funnel=FUNNEL, rho_phi=0.25)  # untouched


def test_evolve_of_a_slotted_class_keeps_it_frozen_and_checks_names():
    @dataclasses.dataclass(frozen=True, slots=True)
    class Slotted:
        x: int
        y: tuple = ()

    state = evolve(Slotted(1, (2,)), x=3)
    assert state == Slotted(3, (2,)) and evolve(state) == state and evolve(state) is not state
    with pytest.raises(dataclasses.FrozenInstanceError):
        state.x = 4
    with pytest.raises(TypeError, match=r"Slotted has no field \['z'\]"):
        evolve(state, z=1)
