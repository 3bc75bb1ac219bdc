"""Stage rules of the detection-and-repair scheme (paper Alg. 2; stl-funnel.md §7.4, §15).

The repair computation itself (R1–R10 with guards and post-repair checks) is
``tlfleet.agent.stl.funnel.Funnel.repair``; this module decides which stage a critical event gets
and holds the collaboration options.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from tlfleet.agent.stl.messages import StatusAnnounce
from tlfleet.agent.stl.task import Task


@dataclass(frozen=True)
class ProtocolParams:
    """Collaboration options (stl-funnel.md §7, §15); defaults are the documented [OUR CHOICE]s."""

    stage2_entry_repair: bool = True  # run R1–R10 (stage 2) on entering stage 2 (paper Alg. 2)
    stage2_repeat_broadcast: bool = True  # later events while c_i = i: stage-3 repair + update
    reset_ce_on_release: bool = False  # keep ce when a follower re-initialises
    release_on_window_end: bool = True  # release followers when the window ends unsatisfied
    first_come_follow: bool = True  # ignore further requests while following
    status_period: float | None = 1.0  # [s] re-announce the peer status this often (None: only
    # on changes) [OUR CHOICE]; the stage-2 rule reads these announcements
    complete_on_satisfaction: bool = True  # §8: F done at the first a ≤ t ≤ b with r < ρ < ρ_max;
    # False runs every sub-task to its window end (F at t > b), as in §11.2's last variant
    f_done_at_goal: bool = True  # F done (with the rule above) only once ρ ≥ r_frac·ρ_max of its
    # first funnel, or ρ^φ > 0 at its look-ahead deadline (docs/stl-saturation.md §6); False:
    # the authors' r < ρ < ρ_max, met even where repairs took r below 0
    followers_detect: bool = False  # followers run no detection (paper Alg. 2 line 5); True: the
    # authors' code behaviour, a follower repairs its local copy (stage 1 while ce ≤ K, else 3)


def stage2_enabled(robot_id: int, task: Task, c: int,
                   peers: Mapping[int, StatusAnnounce]) -> bool:
    """Stage-2 enabling rule (stl-funnel.md §7.4, authors' ``detectStageTwo``).

    True iff someone can help (V_i ≠ {i}), c_i ≠ i, and every v ∈ V_i∖{i} is done (c_v = −1, or its
    whole sequence is done) or works on its own task (c_v = 0) with a relevant deadline (b_v for F,
    a_v for G) later than b_i. A peer whose status is unknown blocks stage 2.
    """
    others = [v for v in task.v_ctrl if v != robot_id]
    if not others or c == robot_id:
        return False
    for v in others:
        status = peers.get(v)
        if status is None:
            return False
        if status.all_done or status.c == -1:
            continue
        if status.c == 0 and status.kind is not None and status.relevant_deadline > task.b:
            continue
        return False
    return True


def choose_stage(ce: int, n_stage1: int, c: int, robot_id: int, stage2_ok: bool) -> int:
    """Alg. 2 lines 7–17: 1 while ce ≤ N_i; then 2 (entry if enabled, or repeat while c_i = i);
    else 3."""
    if ce <= n_stage1:
        return 1
    if c == robot_id or stage2_ok:
        return 2
    return 3
