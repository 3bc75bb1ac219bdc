"""The bus: the bottom layer every tlfleet process talks through (architecture.md §4).

It holds the :class:`~bus.transport.Transport` interface, the Zenoh implementation
(:mod:`bus.zenoh_transport`, the only importer of zenoh in the tree), the in-memory fake for tests
(:mod:`bus.fake`) and the process signal handling (:mod:`bus.signals`). It sits directly above the
protocol (``agent.protocol``: messages, codec, key builders) and below the simulator, the agent
runtime and the coordinator, which share nothing else.
"""

from bus.transport import (
    AliveCallback,
    Closeable,
    QueryHandler,
    RepliesCallback,
    SampleCallback,
    Transport,
    TransportConfig,
    open_transport,
)

__all__ = [
    "AliveCallback",
    "Closeable",
    "QueryHandler",
    "RepliesCallback",
    "SampleCallback",
    "Transport",
    "TransportConfig",
    "open_transport",
]
