"""Optimal prefix–suffix plans for LTL robots (paper Algorithm 1; ltl-planning.md §3–§5).

``plan_robot(scenario, robot_id)`` parses the robot's formula, translates it into a Büchi
automaton, builds the reachable product with the robot's transition system over the regions and
returns the run ``prefix · suffix^ω`` minimising ``prefix_cost + β · suffix_cost``
(β = ``scenario.ltl.suffix_weight``), projected on region names.

Conventions, shared with the LTL agent:

* ``prefix[0]`` (``suffix[0]`` when the prefix is empty) is the state the robot starts in (its
  region, or ``"start"``); the robot follows ``prefix`` once, then ``suffix`` forever;
  consecutive equal names are zero-cost stays (the automaton reads that region's label again);
* the Büchi state is tracked with :func:`buchi_step`, reading the label of the region being
  *left* (the product evaluates guards on the source region, ltl-planning.md §4);
* :func:`replan` restarts from a region and a set of Büchi states (after a restart, or with
  blocked transitions removed by ``TransitionSystem.without_edges``).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterable
from dataclasses import dataclass

from tlfleet.agent.ltl.buchi import Buchi, buchi_step, translate
from tlfleet.agent.ltl.diagnose import explain_unsatisfiable
from tlfleet.agent.ltl.formula import Formula
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.ltl.product import ProductGraph, explore
from tlfleet.agent.ltl.search import optimal_lasso
from tlfleet.agent.ltl.task import is_hoa_task, robot_formula, task_automaton
from tlfleet.agent.ltl.transition_system import (
    Distance,
    EdgeLength,
    TransitionSystem,
    from_scenario,
)
from tlfleet.agent.model.scenario import Scenario
from tlfleet.bus.errors import UnsatisfiableTask

__all__ = ["Plan", "Timings", "buchi_step", "plan", "plan_robot", "replan"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Timings:
    """Wall-clock time of each planning step [s]."""

    parse: float = 0.0
    translate: float = 0.0
    product: float = 0.0
    search: float = 0.0

    @property
    def total(self) -> float:
        return self.parse + self.translate + self.product + self.search


@dataclass(frozen=True)
class Plan:
    """An optimal lasso run, projected on regions.

    ``prefix_run``/``suffix_run`` are the product states ``(region, Büchi state)`` behind
    ``prefix``/``suffix``; ``suffix_run[0]`` is the accepting state the cycle goes through.
    Costs are path lengths [m] (or whatever ``distance`` measures); ``cost = prefix_cost +
    beta · suffix_cost``.
    """

    formula: str
    prefix: tuple[str, ...]
    suffix: tuple[str, ...]
    cost: float
    prefix_cost: float
    suffix_cost: float
    beta: float
    prefix_run: tuple[tuple[str, int], ...]
    suffix_run: tuple[tuple[str, int], ...]
    buchi_states: int
    buchi_edges: int
    product_states: int
    product_edges: int
    timings: Timings
    robot: int | None = None

    def to_dict(self) -> dict:
        """JSON-ready summary (used by ``tlfleet plan --json``)."""
        return {
            "robot": self.robot,
            "formula": self.formula,
            "prefix": list(self.prefix),
            "suffix": list(self.suffix),
            "cost": self.cost,
            "prefix_cost": self.prefix_cost,
            "suffix_cost": self.suffix_cost,
            "beta": self.beta,
            "prefix_run": [list(p) for p in self.prefix_run],
            "suffix_run": [list(p) for p in self.suffix_run],
            "buchi": {"states": self.buchi_states, "edges": self.buchi_edges},
            "product": {"states": self.product_states, "edges": self.product_edges},
            "timings": {
                "parse": self.timings.parse,
                "translate": self.timings.translate,
                "product": self.timings.product,
                "search": self.timings.search,
                "total": self.timings.total,
            },
        }


def _automaton(task: Formula | str | Buchi) -> tuple[Buchi, float, float]:
    """The Büchi automaton of ``task`` and the parse and translate times [s]."""
    if isinstance(task, Buchi):
        return task, 0.0, 0.0
    t0 = time.perf_counter()
    if is_hoa_task(task):  # ltl = { hoa = "…" }
        buchi = task_automaton(task)
        return buchi, 0.0, time.perf_counter() - t0
    tree = parse(task) if isinstance(task, str) else task
    t1 = time.perf_counter()
    buchi = translate(tree)
    t2 = time.perf_counter()
    return buchi, t1 - t0, t2 - t1


def _search(
    buchi: Buchi,
    ts: TransitionSystem,
    initial_pairs: list[tuple[int, int]],
    beta: float,
    robot: int | None,
    parse_time: float,
    translate_time: float,
) -> Plan:
    t0 = time.perf_counter()
    graph: ProductGraph = explore(ts, buchi, initial_pairs)
    t1 = time.perf_counter()
    lasso = optimal_lasso(graph.succ, graph.initial, graph.accepting, beta)
    t2 = time.perf_counter()
    if lasso is None:
        start = ts.names[initial_pairs[0][0]] if initial_pairs else ts.names[ts.initial]
        states = frozenset(q for _r, q in initial_pairs)
        missing = explain_unsatisfiable(buchi, ts, start, states)
        raise UnsatisfiableTask(robot, buchi.formula, missing)

    def run(ids: Iterable[int]) -> tuple[tuple[str, int], ...]:
        return tuple((ts.names[graph.pairs[k][0]], graph.pairs[k][1]) for k in ids)

    prefix_run = run(lasso.prefix)
    suffix_run = run(lasso.cycle)
    timings = Timings(parse_time, translate_time, t1 - t0, t2 - t1)
    result = Plan(
        formula=buchi.formula,
        prefix=tuple(r for r, _q in prefix_run),
        suffix=tuple(r for r, _q in suffix_run),
        cost=lasso.prefix_cost + beta * lasso.cycle_cost,
        prefix_cost=lasso.prefix_cost,
        suffix_cost=lasso.cycle_cost,
        beta=beta,
        prefix_run=prefix_run,
        suffix_run=suffix_run,
        buchi_states=buchi.num_states,
        buchi_edges=buchi.num_edges,
        product_states=graph.num_states,
        product_edges=graph.num_edges,
        timings=timings,
        robot=robot,
    )
    log.debug("plan for %s: %s (%.3f ms)", buchi.formula, result.suffix, 1e3 * timings.total)
    return result


def plan(
    task: Formula | str | Buchi,
    ts: TransitionSystem,
    beta: float = 10.0,
    *,
    robot: int | None = None,
) -> Plan:
    """Optimal plan of ``task`` (formula, text, or an already translated automaton) on ``ts``.

    Raises :class:`tlfleet.bus.errors.UnsatisfiableTask` when no accepting run exists, with what is
    missing, and :class:`tlfleet.bus.errors.FormulaSyntaxError` for text that does not parse.
    """
    buchi, t_parse, t_translate = _automaton(task)
    pairs = [(ts.initial, q) for q in buchi.initial]
    return _search(buchi, ts, pairs, beta, robot, t_parse, t_translate)


def replan(
    task: Formula | str | Buchi,
    ts: TransitionSystem,
    current: str,
    buchi_states: Iterable[int],
    beta: float = 10.0,
    *,
    robot: int | None = None,
) -> Plan:
    """Best plan from region ``current`` when the automaton is in any of ``buchi_states``.

    ``buchi_states`` are the states consistent with the regions visited so far (labels of the
    regions *left*, see :func:`buchi_step`); the label of ``current`` is not yet read. Pass
    the same automaton the states refer to (a ``Buchi``), or the formula: translation is
    deterministic, so its numbering is the same.
    """
    buchi, t_parse, t_translate = _automaton(task)
    states = sorted(set(buchi_states))
    bad = [q for q in states if not 0 <= q < buchi.num_states]
    if bad:
        raise ValueError(f"Büchi states {bad} out of range 0..{buchi.num_states - 1}")
    if not states:
        raise UnsatisfiableTask(
            robot, buchi.formula, "the regions visited so far already violate the task"
        )
    region = ts.index(current)
    pairs = [(region, q) for q in states]
    return _search(buchi, ts, pairs, beta, robot, t_parse, t_translate)


def plan_robot(scenario: Scenario, robot_id: int, distance: Distance | None = None, *,
               buchi: Buchi | None = None, edge_length: EdgeLength | None = None) -> Plan:
    """Optimal plan of LTL robot ``robot_id`` over the scenario's regions (paper Alg. 1).

    ``distance(p, q)`` between region centres defaults to the Euclidean distance [m];
    ``edge_length(source, target)`` over the states (``transition_system``) replaces it. ``buchi``
    is the robot's automaton when the caller has translated it already (an LTL agent keeps it
    to track its Büchi states: one translation, one numbering); otherwise the scenario's parsed
    formula is translated here.
    """
    robot = scenario.robot(robot_id)
    if robot.ltl is None:
        raise ValueError(f"robot {robot_id} has no LTL task")
    ts = from_scenario(scenario, robot_id, distance, edge_length=edge_length)
    buchi, t_parse, t_translate = _automaton(robot_formula(robot) if buchi is None else buchi)
    pairs = [(ts.initial, q) for q in buchi.initial]
    try:
        return _search(
            buchi, ts, pairs, scenario.ltl.suffix_weight, robot_id, t_parse, t_translate
        )
    except UnsatisfiableTask as exc:
        # Name the formula as the scenario wrote it.
        raise UnsatisfiableTask(robot_id, robot.ltl, exc.missing) from None

