"""The policies: one robot's decision per control tick, built from the pure cores.

* ``ltl`` — an LTL robot: Algorithm 1's plan (``tlfleet.agent.ltl``) followed region by region by
  the navigation executor (``tlfleet.agent.nav``), re-planning when the executor is stuck;
* ``stl`` — an STL robot: the funnel controller, the repair stages of Algorithm 2 and collision
  avoidance (``tlfleet.agent.stl``, ``tlfleet.agent.control``);
* ``coupling`` — what STL tasks that name an LTL robot ask of its speed (``ltl`` uses it).

Pure: numbers in, numbers out; ``tlfleet.agent.runtime`` puts them on the bus.
"""
