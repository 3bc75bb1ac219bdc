"""Control laws shared by the agents (stl-funnel.md §6): saturation, collision avoidance. Pure."""
