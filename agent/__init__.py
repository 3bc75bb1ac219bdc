"""tlfleet agents: pure planning/control cores (ltl, stl, nav, control, protocol) and their runtime."""
