"""Navigation for unicycle robots (ltl-planning.md §6, paper §III-A). Pure: stdlib + numpy.

What the LTL agent runtime uses::

    from tlfleet.agent.nav.executor import Executor, ExecutorInputs
    executor = Executor.from_scenario(scenario, robot_id)        # static grid + DWA + limits
    state = executor.initial_state(plan.prefix, plan.suffix)     # region names from the planner
    state, out = executor.step(state, ExecutorInputs(t, (x, y, θ), others))   # at 5 Hz
    # others: (K, 4) rows (id, x, y, θ) of the mocap frame (own row ignored); out.v, out.omega:
    # the command [m/s, rad/s];
    # out.events: RegionVisited, RegionEntered, CycleCompleted, PlanFinished, Stuck,
    # Recovered, Yielding, ReplanRequest, ...;
    # out.progress: target, visits per region, GF rounds, suffix cycles, mode.
    # Answer a ReplanRequest with ExecutorInputs(..., new_plan=(prefix, suffix)).

Edge weights for the LTL transition system (docs/ltl-navigation.md §2: a transition enters no
third region)::

    from tlfleet.agent.nav.keep_out import RegionPaths
    paths = RegionPaths.from_scenario(scenario, robot_id)   # keep-out grids, cached
    paths.length("a", "b")    # [m], inf when every way enters another region
    paths.edge_length         # the transition system's edge_length(source, target)

Modules:

* ``grid``          occupancy grid with clearance layer, inflation, stamping other robots
* ``grid_planner``  A* (with a clearance preference) + line-of-sight smoothing, ``plan_path``,
  ``path_length_function``
* ``keep_out``      paths between regions that enter no third region, the keep-out grids
* ``traffic``       right of way: narrow passages and crossings, the yield's refuge
* ``dwa``           dynamic window approach (Fox, Burgard & Thrun 1997), vectorised
* ``executor``      plan executor: visits, cycles, re-planning, stuck recovery (pure step)
* ``events``        the executor's events and progress record
* ``polyline``      distances to and points along paths
* ``errors``        ``NoPathError``, ``InvalidPlanError``
"""
