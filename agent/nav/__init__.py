"""Navigation for unicycle robots (ltl-planning.md §6): grid planner, DWA, plan executor. Pure."""
