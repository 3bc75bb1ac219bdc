"""The STL corpus (``scenarios/stl/``) as real fleets in lockstep at seed 1, judged from the record.

Each scenario runs through ``tlfleet run`` (router, simulator, one agent process per robot) with
no report files, and ``tests/stl_corpus.py`` judges the recorded run from ``trajectory.csv`` and
``events.jsonl``: every feasible sub-task met (ρ^φ > 0, recomputed with numpy), the infeasible
ones within 0.05 of their best possible, no robot–robot contact, no robot touching a wall or an
obstacle for more than 1 s. A lockstep run of 15–46 s of sim time takes 3–5 s here; the two
longest (41 and 71 s, 5–8 s of wall time) are marked slow. ``bench/stl_maps_bench.py`` runs all of
them at seeds 1–5.
"""

from __future__ import annotations

import pytest
from stl_corpus import CORPUS_DIR, QUICK, SLOW, judge
from system_helpers import run

pytestmark = pytest.mark.system


def _check(name: str, tmp_path) -> None:
    out = tmp_path / name
    result = run(CORPUS_DIR / f"{name}.toml", out, seed=1, report=False, figures=False,
                 rrd=False)
    assert result.clean, result.summary_text
    verdict = judge(name, out)
    for s in verdict.subtasks:
        assert s.ok, (f"{name}: robot {s.robot} sub-task {s.index + 1} ({s.text}): "
                      f"ρ = {s.rho:+.4f}" + ("" if s.best is None else f", best {s.best:+.3f}"))
    assert verdict.robot_contacts == 0
    assert verdict.wall_beyond_1s == 0


@pytest.mark.parametrize("name", QUICK)
def test_corpus_scenario(name, tmp_path):
    _check(name, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("name", SLOW)
def test_corpus_scenario_slow(name, tmp_path):
    _check(name, tmp_path)
