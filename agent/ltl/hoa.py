"""Export to the Hanoi Omega-Automata format, HOA v1 (ltl-planning.md §2, "Interoperable").

State-based Büchi acceptance (``Acceptance: 1 Inf(0)``, ``acc-name: Buchi``); edge labels are
Boolean expressions over AP indices (``[0&!1 | 2]``), so the output can be fed to Spot's
``autfilt``. Format: https://adl.github.io/hoaf/
"""

from __future__ import annotations

from tlfleet.agent.ltl.bdd import FALSE, TRUE, disjoin
from tlfleet.agent.ltl.buchi import Buchi
from tlfleet.agent.ltl.guards import cube_to_string


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _label(buchi: Buchi, guard: int) -> str:
    if guard is TRUE:
        return "t"
    if guard is FALSE:
        return "f"
    numbers = [str(i) for i in range(len(buchi.atoms))]
    cubes = buchi.alphabet.cubes(guard)
    return " | ".join(cube_to_string(c, numbers, and_="&") for c in cubes).replace(
        "true", "t"
    )


def to_hoa(buchi: Buchi, name: str | None = None) -> str:
    """HOA v1 text of ``buchi``; ``name`` defaults to the formula it was translated from."""
    deterministic = len(buchi.initial) <= 1 and all(
        not a & b
        for out in buchi.edges
        for i, (_d1, a) in enumerate(out)
        for _d2, b in out[i + 1 :]
    )
    complete = all(
        disjoin(g for _d, g in out) is TRUE for out in buchi.edges
    ) and len(buchi.initial) >= 1
    properties = ["trans-labels", "explicit-labels", "state-acc"]
    if deterministic:
        properties.append("deterministic")
    if complete:
        properties.append("complete")
    lines = [
        "HOA: v1",
        f"name: {_quote(name if name is not None else buchi.formula)}",
        f"States: {buchi.num_states}",
        *(f"Start: {q}" for q in buchi.initial),
        f"AP: {len(buchi.atoms)}" + "".join(f" {_quote(a)}" for a in buchi.atoms),
        "acc-name: Buchi",
        "Acceptance: 1 Inf(0)",
        f"properties: {' '.join(properties)}",
        "--BODY--",
    ]
    for q, out in enumerate(buchi.edges):
        lines.append(f"State: {q}" + (" {0}" if q in buchi.accepting else ""))
        for dst, guard in out:
            lines.append(f"[{_label(buchi, guard)}] {dst}")
    lines.append("--END--")
    return "\n".join(lines) + "\n"

