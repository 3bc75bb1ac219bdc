"""The automaton of a robot's LTL task (ltl-planning.md §2).

A scenario task is a formula — translated by :func:`tlfleet.agent.ltl.buchi.translate` — or, for
``ltl = { hoa = "file.hoa" }``, the text ``hoa:<absolute path>``
(:data:`tlfleet.agent.ltl.hoa_reader.HOA_TASK_PREFIX`, set by ``tlfleet.agent.scenario.loader``) of
an automaton made by another tool, read by :func:`tlfleet.agent.ltl.hoa_reader.read_hoa_file`. This
module is the one place that tells the two apart, so neither the translator nor the HOA reader
imports the other.
"""

from __future__ import annotations

import functools

from tlfleet.agent.ltl.buchi import Buchi, translate
from tlfleet.agent.ltl.formula import Formula
from tlfleet.agent.ltl.hoa_reader import HOA_TASK_PREFIX, read_hoa_file
from tlfleet.agent.ltl.parser import parse
from tlfleet.agent.model.scenario import Robot


def is_hoa_task(task: Formula | str) -> bool:
    """Whether ``task`` names an HOA file rather than a formula."""
    return isinstance(task, str) and task.startswith(HOA_TASK_PREFIX)


def task_automaton(task: Formula | str) -> Buchi:
    """The Büchi automaton of a task: the HOA file it names, or the formula's translation."""
    if is_hoa_task(task):
        return read_hoa_file(task[len(HOA_TASK_PREFIX):])
    return translate(task)


@functools.lru_cache(maxsize=512)
def task_formula(text: str) -> Formula | str:
    """A scenario task as :func:`task_automaton` takes it: the formula's tree, parsed once per
    process and text (trees are immutable, so every user shares one), or, for an automaton task,
    its ``hoa:<path>`` text. Raises ``LtlSyntaxError`` for a formula that does not parse."""
    return text if is_hoa_task(text) else parse(text)


def robot_formula(robot: Robot) -> Formula | str:
    """The LTL task of ``robot`` (:func:`task_formula` of its text)."""
    if robot.ltl is None:
        raise ValueError(f"robot {robot.id} has no LTL task")
    return task_formula(robot.ltl)


@functools.lru_cache(maxsize=512)
def text_automaton(text: str) -> Buchi:
    """The automaton of a scenario task's text, built once per process and text: the loader's
    emptiness check translates it, and the agent plans, replans and tracks its Büchi states on
    that same automaton (automata are never modified after construction)."""
    return task_automaton(task_formula(text))


def robot_automaton(robot: Robot) -> Buchi:
    """The automaton of ``robot``'s LTL task (:func:`text_automaton` of its text)."""
    if robot.ltl is None:
        raise ValueError(f"robot {robot.id} has no LTL task")
    return text_automaton(robot.ltl)
