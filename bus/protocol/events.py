"""Who may publish which events, on which key, with which fields (architecture.md §2).

Every process publishes its events on a key of its own, ``event/<role>/<id>``
(:func:`tlfleet.bus.protocol.keys.event`): ``event/sim/0``, ``event/agent/<id>``,
``event/coordinator/0``. In a secured fleet the access policy lets each identity write only its
own key, so the key an event arrives on *is* its publisher (the router refuses any other put);
the recorder then accepts an event only when its claimed ``source`` is that key's identity
(:func:`source_of_key`), and a kind only the simulator makes (``sim_done``, ``sim_stats``,
contacts, watchdog stops, …) only from the simulator's key. Without ``--secure`` the same
discipline holds among honest processes, but any local process can still publish on any key.

An event's ``data`` is a free map on the wire; :data:`FIELDS` names, per kind, the fields the
coordinator and the report read and the types they must have. :func:`data_problem` says what is
wrong with one: such an event is counted as malformed and dropped, never used (a ``sim_stats``
whose ``due`` is a string used to crash ``tlfleet run`` while it wrote the summary).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

#: the kinds only the simulator makes
SIM_KINDS = frozenset({"sim_done", "sim_stats", "contact", "deadline_miss", "watchdog_stop",
                       "stale_command", "tracking_lost", "geofence"})  # the last two: tlfleet hw
#: the kinds only an agent makes
AGENT_KINDS = frozenset({"agent_stats", "stale_mocap", "resumed", "plan_ready", "critical_event",
                         "repair", "recovery", "collab_request", "collab_release",
                         "collab_follow", "subtask_done", "peers_unreachable"})

INT = "an integer"
NUM = "a number"
STR = "a string"
BOOL = "true or false"
LIST = "a list"
MAP = "a map"
NONE = "null"
ID = "a robot id or 'wall'"

_CHECKS = {
    INT: lambda v: isinstance(v, int) and not isinstance(v, bool),
    NUM: lambda v: isinstance(v, int | float) and not isinstance(v, bool),
    STR: lambda v: isinstance(v, str),
    BOOL: lambda v: isinstance(v, bool),
    LIST: lambda v: isinstance(v, list | tuple),
    MAP: lambda v: isinstance(v, dict),
    NONE: lambda v: v is None,
    ID: lambda v: (isinstance(v, int) and not isinstance(v, bool)) or v == "wall",
}

#: kind -> {field: the accepted types}; a field may be absent, but when present it has a type
#: of its tuple. Only the fields something reads are listed; others pass as they are.
FIELDS: dict[str, dict[str, tuple[str, ...]]] = {
    "sim_stats": {"mode": (STR,), "ticks": (INT,), "wall_time": (NUM,), "due": (INT,),
                  "missed": (INT,), "commands": (INT,), "deadline_misses": (INT,),
                  "contacts": (INT,), "watchdog_stops": (INT,), "overruns": (INT,),
                  "early": (INT,), "malformed": (INT,), "stale_commands": (INT,),
                  "ignored": (MAP,), "malformed_by_key": (MAP,), "backfill": (MAP,),
                  "missed_by_robot": (MAP,), "latency_p50_ms": (NUM,),
                  "latency_p99_ms": (NUM,), "latency_max_ms": (NUM,),
                  "latency_p99_ms_by_robot": (MAP,), "latency_histogram_ms": (MAP,)},
    "sim_done": {"ticks": (INT,)},
    "deadline_miss": {"robot": (INT,), "seq": (INT,), "count": (INT,)},
    "watchdog_stop": {"robot": (INT,), "last_command_t": (NUM, NONE)},
    "stale_command": {"robot": (INT,), "command_t": (NUM,)},
    "contact": {"a": (ID,), "b": (ID,), "what": (STR,)},
    "tracking_lost": {"robots": (LIST,), "age": (MAP,), "lost_after": (NUM,)},
    "geofence": {"robot": (INT,), "x": (NUM,), "y": (NUM,), "fence": (LIST,)},
    "malformed_message": {"key": (STR,), "count": (INT,)},
    "stale_mocap": {"silence": (NUM,), "sim_silence": (NUM,), "last_seq": (INT,)},
    "critical_event": {"stage": (INT,), "ce": (INT,), "rho": (NUM,), "subtask": (INT,),
                       "follow": (INT,)},
    "repair": {"stage": (INT,), "r": (NUM,), "rho_max": (NUM,), "lower": (NUM,),
               "subtask": (INT,)},
    "recovery": {"r": (NUM,), "r_before": (NUM, NONE), "rho": (NUM,), "subtask": (INT,)},
    "collab_request": {"subtask": (INT,), "receivers": (LIST,)},
    "collab_release": {"subtask": (INT,), "receivers": (LIST,)},
    "collab_follow": {"requester": (INT,), "previous": (INT,), "subtask": (INT, NONE)},
    "subtask_done": {"subtask": (INT,), "satisfied": (BOOL,), "r": (NUM, NONE),
                     "rho_phi": (NUM, NONE), "events": (LIST,), "ended_by": (STR,),
                     "recoveries": (INT,)},
    "peers_unreachable": {"peers": (LIST,), "lost": (LIST,), "back": (LIST,)},
    "fault": {"error": (STR,)},
    "agent_stats": {},
    # the coordinator's own (recorded, never received; read back from events.jsonl)
    "process_died": {"process": (STR,), "how": (STR,), "returncode": (INT, NONE),
                     "wall": (NUM,)},
    "process_recovered": {"process": (STR,), "lost_at": (NUM,), "how": (STR,)},
    "link_lost": {"process": (STR,), "wall": (NUM,)},
    "link_restored": {"process": (STR,), "wall": (NUM,), "lost_for": (NUM,)},
    "token_blip": {"process": (STR,), "lost_at": (NUM,), "lost_for": (NUM,)},
    "agent_silent": {"robot": (INT,), "last_status_t": (NUM,), "silence": (NUM,)},
    "agent_back": {"robot": (INT,), "silence": (NUM,)},
    "fault_start": {"spec": (STR,), "kind": (STR,), "targets": (LIST,), "wall": (NUM,),
                    "error": (STR, NONE)},
    "fault_end": {"spec": (STR,), "kind": (STR,), "targets": (LIST,), "wall": (NUM,),
                  "lasted": (NUM, NONE), "error": (STR, NONE)},
}


def data_problem(kind: str, data: Any) -> str | None:
    """Why ``data`` cannot be the payload of an event of ``kind``, or None."""
    if not isinstance(data, Mapping):
        return f"data of a {kind!r} event must be a map, found {type(data).__name__}"
    for name, types in FIELDS.get(kind, {}).items():
        if name not in data:
            continue
        value = data[name]
        if not any(_CHECKS[t](value) for t in types):
            shown = repr(value)[:40]
            return f"{kind}.{name} must be {' or '.join(types)}, found {shown}"
    if kind == "sim_stats":
        missed, due = data.get("missed"), data.get("due")
        if isinstance(missed, int) and isinstance(due, int) and not 0 <= missed <= due:
            return f"sim_stats.missed = {missed} is outside [0, due = {due}]"
    for name in ("t", "command_t"):
        value = data.get(name)
        if isinstance(value, float) and math.isinf(value):
            return f"{kind}.{name} is infinite"
    return None


def source_of_key(role: str, ident: str) -> str | None:
    """The ``Event.source`` an event on ``event/<role>/<ident>`` must claim, or None for a key no
    process of a fleet publishes on."""
    if role == "sim" and ident == "0":
        return "sim"
    if role == "agent" and ident.isdigit():
        return f"agent/{int(ident)}"
    if role == "coordinator" and ident == "0":
        return "coordinator"
    return None


def role_of_source(source: str) -> tuple[str, str] | None:
    """``(role, id)`` of an ``Event.source`` (``sim`` → ``("sim", "0")``, ``agent/3`` →
    ``("agent", "3")``), the key it publishes on; None when it names no process."""
    if source in ("sim", "coordinator"):
        return source, "0"
    head, _, tail = source.partition("/")
    if head == "agent" and tail.isdigit():
        return "agent", str(int(tail))
    return None
