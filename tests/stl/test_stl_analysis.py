"""Concavity warnings (Assumption 1), suprema and the default ρ_opt (stl-funnel.md §3)."""

from __future__ import annotations

import math
import warnings

import pytest
from tlfleet.agent.stl.analysis import curvature, literal_sup, non_concave_literals
from tlfleet.agent.stl.errors import StlConcavityWarning, StlTaskError
from tlfleet.agent.stl.parser import parse_psi, parse_task
from tlfleet.agent.stl.robustness import smooth_and
from tlfleet.agent.stl.syntax import literals, predicate_function
from tlfleet.agent.stl.task import build_task, default_rho_opt


@pytest.mark.parametrize(("text", "exogenous", "expected"), [
    ("dist(p3, [0,-2]) <= 0.1", (), "concave"),
    ("dist(p3, [0,-2]) >= 0.1", (), "convex"),
    ("x3 + 2 * y3 <= 1", (), "affine"),
    ("2 - x3 * y3 >= 0", (), "unknown"),
    ("angdist(th2, th1) <= 0.09", (), "concave"),
    ("dist(p2 - p1, [sin(th1), -cos(th1)]) <= 0.1", (), "unknown"),
    ("dist(p2 - p1, [sin(th1), -cos(th1)]) <= 0.1", (1,), "concave"),
    ("-norm(p1 - p2) / 2 >= -1", (), "concave"),
    ("3 * abs(x1 - 1) <= 1", (), "concave"),
    ("sin(x1) <= 1", (), "unknown"),
])
def test_curvature_of_h(text, exogenous, expected):
    (literal,) = literals(parse_psi(text))
    assert curvature(predicate_function(literal), frozenset(exogenous)) == expected


def test_non_concave_literals_positive_and_negated():
    psi = parse_psi("dist(p1, p2) >= 0.5 & !(dist(p1, p2) <= 0.5) & !(dist(p1, p2) >= 0.5) "
                    "& dist(p1, [0,0]) <= 1 & x1 <= 2")
    bad = non_concave_literals(psi)
    assert [str(b) for b in bad] == [str(literals(psi)[0]), str(literals(psi)[1])]


def test_build_task_warns_naming_the_predicate():
    with pytest.warns(StlConcavityWarning, match=r"robot 4 sub-task 1 .*predicate "
                                                 r"'dist\(p4, p3\) >= 1' is not concave"):
        build_task("G[5,30] (dist(p4, p3) >= 1 & dist(p4, p5) <= 1)", 4, rho_opt=1.0)


def test_scenario3_formation_does_not_warn_when_robot1_is_ltl():
    text = "G[10,100] (dist(p2 - p1, [sin(th1), -cos(th1)]) <= 0.1 & angdist(th2, th1) <= 0.09)"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        task = build_task(text, 2, stl_ids=[2, 3, 4])
    assert task.participants == (1, 2) and task.v_ctrl == (2,)
    with pytest.warns(StlConcavityWarning, match="dist\\(p2 - p1"):
        build_task(text, 2, stl_ids=[1, 2])


@pytest.mark.parametrize(("text", "sup"), [
    ("dist(p3, [0,-2]) <= 0.1", 0.1),
    ("angdist(th2, th1) <= 0.09", 0.09),
    ("1 >= dist(p4, p5)", 1.0),
    ("!(dist(p1, p2) <= 0.5)", math.inf),
    ("!(dist(p1, p2) >= 0.5)", 0.5),
    ("x1 <= 1", math.inf),
    ("sin(th1) <= 0.5", 1.5),
    ("0.2 - 2 * norm(p1) >= 0", 0.2),
])
def test_literal_sup(text, sup):
    (literal,) = literals(parse_psi(text))
    assert literal_sup(literal) == pytest.approx(sup)


def test_default_rho_opt_is_lse_of_suprema():
    # stl-funnel.md §11.6: LSE_η(0.7, 0.1) = 0.0997524 and LSE_η(1, 1) = 0.9306853
    psi = parse_psi("dist(p3, [1.5,-1.5]) <= 0.1 & dist(p3, p4) <= 0.7")
    assert default_rho_opt(psi, 10.0) == pytest.approx(0.0997524, abs=1e-6)
    psi = parse_psi("dist(p4, p3) <= 1 & dist(p4, p5) <= 1")
    assert default_rho_opt(psi, 10.0) == pytest.approx(0.9306853, abs=1e-6)
    assert smooth_and([1.0, 1.0], 10.0) == pytest.approx(0.9306853, abs=1e-6)


def test_rho_opt_override_and_unbounded_error():
    task = build_task("F[57,58] (dist(p3, [1.5,-1.5]) <= 0.1 & dist(p3, p4) <= 0.7)", 3,
                      rho_opt=0.1)
    assert task.rho_opt == 0.1
    with pytest.raises(StlTaskError, match=r"robot 1 sub-task 1 .*unbounded; give rho_opt"):
        build_task("G[0,1] x1 <= 1", 1)
    assert build_task("G[0,1] x1 <= 1", 1, rho_opt=2.0).rho_opt == 2.0


def test_task_errors_owner_absent_and_top():
    with pytest.raises(StlTaskError, match="does not involve robot 5's own state"):
        build_task("G[0,1] (dist(p1, p2) <= 1)", 5)
    with pytest.raises(StlTaskError, match="nothing to control"):
        build_task(parse_task("G[0,1] true"), 5)
