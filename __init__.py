"""tlfleet: a distributed runtime for robot fleets under LTL and STL tasks.

The package's subpackages are its layers, from the ground up (docs/architecture.md §4):

* ``tlfleet.bus`` — the ground floor: the error hierarchy (``bus.errors``), the wire protocol
  (``bus.protocol``: messages, codec, key expressions) and the transports (``bus.transport``, the
  in-memory ``bus.fake``, the Eclipse Zenoh implementation ``bus.zenoh``);
* ``tlfleet.agent`` — the robot side: the scenario model (``agent.model``), the pure cores
  (``agent.ltl``, ``agent.stl``, ``agent.nav``, ``agent.control``), scenario files
  (``agent.scenario``), the policies (``agent.policy``) and the agent process (``agent.runtime``);
* ``tlfleet.sim`` — the world's side: the simulator process and the zenoh router process
  (``sim.router``);
* ``tlfleet.coordinator`` — launching, recording, supervising and reporting a run;
* ``tlfleet.cli`` — the ``tlfleet`` command (``python -m tlfleet.cli``).
"""
