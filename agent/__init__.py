"""The robot side of tlfleet, from the data up to the process (docs/architecture.md §4).

* ``model`` — the scenario model: immutable data every layer above shares;
* ``ltl``, ``stl``, ``nav``, ``control`` — the pure cores: numbers in, numbers out;
* ``scenario`` — scenario files: TOML in, a checked model out (parses and checks the tasks);
* ``policy`` — one robot's decision per tick, built from the cores (LTL and STL robots);
* ``runtime`` — the agent process: a policy on the bus;
* ``evolve`` — :func:`dataclasses.replace` for the per-tick states, faster.
"""
