"""Messages between STL agents (stl-funnel.md §7.5 collaboration protocol, §7.4 peer status).

Plain frozen dataclasses addressed by robot id (``receiver``); the runtime encodes them with the
project codec. A funnel is sent whole, t_r included ([OUR CHOICE]: the authors' code omitted t_r).

* :class:`CollabRequest`: requester i enters the second repair stage (paper Alg. 2 lines 10–12)
  and asks each j ∈ V_i∖{i} to follow ψ_i with this funnel.
* :class:`CollabUpdate`: a later repair of the requester while c_i = i (lines 13–15).
* :class:`CollabRelease`: the requester's sub-task is over (c_i: i → −1, lines 23–24 and 29).
* :class:`StatusAnnounce`: an agent's c and active sub-task (type, a, b), sent when they change; the
  stage-2 enabling rule (§7.4) reads them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from tlfleet.agent.stl.funnel import Funnel


@dataclass(frozen=True, slots=True)
class CollabRequest:
    sender: int
    receiver: int
    subtask: int  # index of the requester's sub-task whose ψ the follower adopts
    funnel: Funnel
    c: int = 0  # the requester's c (= sender)


@dataclass(frozen=True, slots=True)
class CollabUpdate:
    sender: int
    receiver: int
    subtask: int
    funnel: Funnel


@dataclass(frozen=True, slots=True)
class CollabRelease:
    sender: int
    receiver: int
    subtask: int


@dataclass(frozen=True, slots=True)
class StatusAnnounce:
    """Peer status (stl-funnel.md §14 ``PeerStatus``): c ∈ {0 own, sender requesting, −1 done};
    ``kind``/``a``/``b`` of the active sub-task (``None`` when none is active)."""

    sender: int
    receiver: int
    c: int
    subtask: int
    kind: Literal["G", "F"] | None
    a: float
    b: float
    all_done: bool = False

    @property
    def relevant_deadline(self) -> float:
        return self.b if self.kind == "F" else self.a


Message = CollabRequest | CollabUpdate | CollabRelease | StatusAnnounce
