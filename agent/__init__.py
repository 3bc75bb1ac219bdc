"""tlfleet agents: the pure cores (ltl, stl, nav, control, protocol, scenario) and their runtime."""
