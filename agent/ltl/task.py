"""The automaton of a robot's LTL task (ltl-planning.md §2; issue 16 "HOA input").

A scenario task is a formula — translated by :func:`agent.ltl.buchi.translate` — or, for
``ltl = { hoa = "file.hoa" }``, the text ``hoa:<absolute path>``
(:data:`agent.ltl.hoa_reader.HOA_TASK_PREFIX`, set by ``agent.scenario.loader``) of an automaton
made by another tool, read by :func:`agent.ltl.hoa_reader.read_hoa_file`. This module is the one
place that tells the two apart, so neither the translator nor the HOA reader imports the other.
"""

from __future__ import annotations

from agent.ltl.buchi import Buchi, translate
from agent.ltl.formula import Formula
from agent.ltl.hoa_reader import HOA_TASK_PREFIX, read_hoa_file


def is_hoa_task(task: Formula | str) -> bool:
    """Whether ``task`` names an HOA file rather than a formula."""
    return isinstance(task, str) and task.startswith(HOA_TASK_PREFIX)


def task_automaton(task: Formula | str) -> Buchi:
    """The Büchi automaton of a task: the HOA file it names, or the formula's translation."""
    if is_hoa_task(task):
        return read_hoa_file(task[len(HOA_TASK_PREFIX):])
    return translate(task)
