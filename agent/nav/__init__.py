"""Navigation for unicycle robots (ltl-planning.md §6, paper §III-A). Pure: stdlib + numpy.

What the LTL agent runtime uses::

    from tlfleet.agent.nav.executor import Executor, ExecutorInputs
    executor = Executor.from_scenario(scenario, robot_id)        # static grid + DWA + limits
    state = executor.initial_state(plan.prefix, plan.suffix)     # region names from the planner
    state, out = executor.step(state, ExecutorInputs(t, (x, y, θ), others))   # at 5 Hz
    # others: (K, 4) rows (id, x, y, θ) of the mocap frame (own row ignored); out.v, out.omega:
    # the command [m/s, rad/s];
    # out.events: RegionVisited, CycleCompleted, PlanFinished, Stuck, ReplanRequest, ...;
    # out.progress: target, visits per region, GF rounds, suffix cycles, mode.
    # Answer a ReplanRequest with ExecutorInputs(..., new_plan=(prefix, suffix)).

Edge weights for the LTL transition system (ltl-planning.md §3)::

    from tlfleet.agent.nav.grid_planner import path_length_function
    distance = path_length_function(scenario)     # distance(p, q) -> path length [m], cached

Modules:

* ``grid``          occupancy grid with clearance layer, inflation, stamping other robots
* ``grid_planner``  A* + line-of-sight smoothing, ``plan_path``, ``path_length_function``
* ``dwa``           dynamic window approach (Fox, Burgard & Thrun 1997), vectorised
* ``executor``      plan executor: visits, cycles, re-planning, stuck recovery (pure step)
* ``events``        the executor's events and progress record
* ``polyline``      distances to and points along paths
* ``errors``        ``NoPathError``, ``InvalidPlanError``
"""
