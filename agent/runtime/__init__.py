"""The thin runtime around the pure cores: the transport (the only zenoh importer in agent/)
and the agent processes (architecture.md §1, §4)."""
