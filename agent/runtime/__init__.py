"""The agent processes around the pure cores (architecture.md §1, §4); they talk through the bus.

* ``main``: ``tlfleet agent``'s entry point, dispatching on the robot's task;
* ``config``: ``AgentConfig``, the typed settings of one agent process;
* ``loop``: ``AgentLoop`` — decode → pure ``Core.step`` → publish, with the time protocol of
  architecture.md §3 (start, due frames, stale mocap, malformed payloads, stop);
* ``inbox``: thread-safe hand-over from transport callbacks (latest frame, controls, collab
  messages, malformed counting);
* ``collab`` / ``peers``: STL collaboration messages on the wire and their query/reply link;
* ``ltl_agent`` / ``stl_agent``: the pure policies (``tlfleet.agent.policy.ltl``,
  ``tlfleet.agent.policy.stl``) adapted to the loop, and their process ``main``; ``process``: what
  every agent process does around its loop.
"""
