"""Sub-commands of the tlfleet CLI (see coordinator.cli)."""
