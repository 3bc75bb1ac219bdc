"""The thin runtime around the pure cores: the transport (the only zenoh importer in agent/)
and the agent processes (architecture.md §1, §4).

* ``transport``: ``Transport`` (zenoh / in-memory fake), shared CLI flags, signal handling;
* ``loop``: ``AgentLoop`` — decode → pure ``Core.step`` → publish, with the time protocol of
  architecture.md §3 (start, due frames, stale mocap, malformed payloads, stop);
* ``inbox``: thread-safe hand-over from transport callbacks (latest frame, controls, collab
  messages, malformed counting);
* ``collab`` / ``peers``: STL collaboration messages on the wire and their query/reply link;
* ``ltl_agent`` / ``stl_agent``: the two cores and their process ``main``; ``process``: what
  every agent process does around its loop.
"""
