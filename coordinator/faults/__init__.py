"""Injected faults: planned, scheduled on sim time, carried out where the fleet runs.

* ``plan`` — a run's faults (the scenario's and ``--fault``), checked before anything starts;
* ``schedule`` — firing each fault at its sim time;
* ``on_hosts`` — link cuts and partitions on network-namespace hosts;
* ``handoff`` — a compose fleet's faults, handed by the coordinator to the host's executor;
* ``docker_executor`` — that executor: the docker commands run on the host.
"""
