"""The public API (``tlfleet/__init__.py``): cheap to import, every name resolves and is
documented, the API page is generated from the docstrings, and ``docs/api_example.py`` runs and
prints what independent computations give."""

from __future__ import annotations

import itertools
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
import tlfleet

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "api_example.py"


def test_import_is_lazy() -> None:
    code = ("import sys, tlfleet\n"
            "heavy = [m for m in ('numpy', 'zenoh', 'matplotlib', 'rerun', 'tlfleet.agent') "
            "if m in sys.modules]\nprint(heavy)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize("name", tlfleet.__all__)
def test_every_public_name_resolves_with_a_docstring(name: str) -> None:
    value = getattr(tlfleet, name)
    assert (value.__doc__ or "").strip(), f"tlfleet.{name} has no docstring"
    assert name in dir(tlfleet)


def test_all_lists_the_exports() -> None:
    assert set(tlfleet.__all__) == {*tlfleet._EXPORTS, "monitor_run", "trajectory_frame"}


def test_unknown_names_are_attribute_errors() -> None:
    with pytest.raises(AttributeError, match="no attribute 'nothing_here'"):
        _ = tlfleet.nothing_here


def test_the_api_page_lists_every_public_name(tmp_path: Path) -> None:
    pytest.importorskip("pdoc")
    done = subprocess.run([sys.executable, "-m", "pdoc", "--docformat", "restructuredtext",
                           "-o", str(tmp_path), "tlfleet"], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    page = (tmp_path / "tlfleet.html").read_text()
    text = re.sub(r"<[^>]+>", "", page)
    for name in tlfleet.__all__:
        assert f'id="{name}"' in page, name
        # the docstring is on the page: the longest run of plain words of its first line
        runs = re.findall(r"[^\W\d_]+(?:\s+[^\W\d_]+)+",
                          getattr(tlfleet, name).__doc__.strip().splitlines()[0])
        phrase = max(runs, key=len)
        assert re.search(r"\s+".join(phrase.split()), text), (name, phrase)


def _numbers(text: str, pattern: str) -> tuple[str, ...]:
    match = re.search(pattern, text, re.M)
    assert match is not None, f"{pattern!r} not in:\n{text}"
    return match.groups()


def test_the_example_runs_and_prints_the_right_numbers() -> None:
    from tlfleet.agent.ltl.lasso import holds

    done = subprocess.run([sys.executable, str(EXAMPLE)], capture_output=True, text=True,
                          timeout=300, cwd=ROOT / "docs")
    assert done.returncode == 0, done.stderr
    out = done.stdout
    formula = "G F a & G F b & G !c"
    states, edges = map(int, _numbers(out, r"^buchi: (\d+) states, (\d+) edges$"))
    buchi = tlfleet.translate(formula)
    assert (states, edges) == (buchi.num_states, buchi.num_edges)
    assert "HOA: v1" in out

    # the plan: its lasso word satisfies the task (exact evaluation), and its printed cost is the
    # lengths between the region centres, prefix + 10 x suffix
    prefix, suffix, cost = _numbers(out, r"^plan: prefix (.+), suffix \((.+)\)\^w, cost (\S+)$")
    prefix, suffix = prefix.split(" -> "), suffix.split(" -> ")
    centre = {"start": (0.0, -1.0), "a": (0.0, 0.0), "b": (3.0, 4.0), "c": (3.0, 0.0)}
    assert suffix[0] == prefix[-1] and suffix[-1] == suffix[0]

    def length(path: list[str]) -> float:
        return sum(math.dist(centre[p], centre[q]) for p, q in itertools.pairwise(path))

    assert float(cost) == pytest.approx(length(prefix) + 10.0 * length(suffix), abs=1e-3)

    def letter(region: str) -> frozenset[str]:
        return frozenset() if region == "start" else frozenset({region})

    assert holds(formula, [letter(r) for r in prefix[:-1]], [letter(r) for r in suffix[:-1]])
    # and no cheaper plan exists: a must be visited from the start, b and a alternate
    assert float(cost) == pytest.approx(1.0 + 5.0 + 10.0 * 10.0, abs=1e-3)

    # F[5,15] dist(p1, p2) <= 0.6 with p1 = (0.1 t, 0), p2 = (1, 0.5): closest at t = 10 s, 0.5 m
    (offline,) = _numbers(out, r"^robustness: (\S+)$")
    (online,) = _numbers(out, r"^online: (\S+)$")
    assert float(offline) == pytest.approx(0.1, abs=1e-6)
    assert float(online) == float(offline)

    # the run: robots 3 and 4 keep 0.3 m from robots 1 and 2 (task: <= 0.6) the whole time
    assert "run: scenario2, 901 samples, robots [1, 2, 3, 4]" in out
    for robot in (3, 4):
        (rho,) = _numbers(out, rf"^robot {robot}: rho = (\S+)$")
        assert float(rho) == pytest.approx(0.3, abs=1e-5)


def test_trajectory_frame_needs_pandas_or_gives_the_columns() -> None:
    import numpy as np

    traj = tlfleet.Trajectory(np.array([0.0, 0.1]), {2: np.zeros((2, 3)), 1: np.ones((2, 3))})
    try:
        import pandas  # noqa: F401
    except ImportError:
        with pytest.raises(ImportError, match="pip install pandas"):
            tlfleet.trajectory_frame(traj)
        return
    frame = tlfleet.trajectory_frame(traj)
    assert list(frame.columns) == ["t", "x1", "y1", "th1", "x2", "y2", "th2"]
