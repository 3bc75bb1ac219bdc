"""Which replayed agent events the recorder has already recorded.

An agent publishes its recent events again when the coordinator's token returns after a loss
(:mod:`tlfleet.agent.runtime.event_log`): delivery is at least once. :class:`EventDedup` remembers
the identity — source, kind, sim time and data, without the ``replayed`` mark — of the last
:data:`REMEMBERED` events of each source, and admits a replayed event only when its original
is not among them. Originals are always admitted: two identical events published twice are two
facts, and only a replay can be a copy.

The bound is per source and four times an agent's replay capacity, so an original a replay can
repeat is still remembered however many events came in between.
"""

from __future__ import annotations

import json

from tlfleet.bus.protocol.messages import EVENT_REPLAYED, Event
from tlfleet.coordinator.record.rundir import json_default

# identities kept per source: four times an agent's replay capacity
# (tlfleet.agent.runtime.event_log.CAPACITY; tests/runtime/test_runtime_event_log.py checks it)
REMEMBERED = 256
SOURCES = 1024  # sources remembered at most (a fleet has one per process)


def identity(event: Event) -> str:
    """The event's source, kind, t and data without the replay mark, as one string."""
    data = {k: v for k, v in event.data.items() if k != EVENT_REPLAYED}
    return json.dumps([event.source, event.kind, event.t, data], sort_keys=True,
                      default=json_default, allow_nan=True)


class EventDedup:
    """Admits every original event and each replayed one not yet recorded."""

    def __init__(self, remembered: int = REMEMBERED):
        self.remembered = remembered
        # source -> the identities of its last events, oldest first (a dict as an ordered set)
        self._seen: dict[str, dict[str, None]] = {}
        self.replayed = 0  # replayed events admitted (their original was lost)
        self.duplicates = 0  # replayed events dropped (their original was recorded)

    def admit(self, event: Event) -> bool:
        """True when ``event`` should be recorded."""
        key = identity(event)
        seen = self._seen.get(event.source)
        if seen is None:
            if len(self._seen) >= SOURCES:  # a flood of made-up sources: remember none of them
                return True
            seen = self._seen[event.source] = {}
        if event.data.get(EVENT_REPLAYED) is True:
            if key in seen:
                self.duplicates += 1
                return False
            self.replayed += 1
        if key not in seen:
            seen[key] = None
            if len(seen) > self.remembered:
                del seen[next(iter(seen))]
        return True
