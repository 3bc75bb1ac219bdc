"""The pymunk simulator process: robot hardware and motion capture (architecture.md §1, §3).

* ``tlfleet.sim.world`` — the pymunk world (walls, obstacles, velocity-tracking robots, disturbance,
  mocap noise, contacts, watchdog); the only pymunk importer, free of any transport.
* ``tlfleet.sim.lockstep`` — which robots are due at a tick, collecting their commands (lockstep and
  realtime), free of sockets and threads.
* ``tlfleet.sim.clock`` — tick ↔ sim time, wall-clock pacing of realtime mode.
* ``tlfleet.sim.stats`` — frame → command latency and missed control deadlines.
* ``tlfleet.sim.process`` — ``main(args)``: the loop on the transport (``tlfleet sim``).
"""
