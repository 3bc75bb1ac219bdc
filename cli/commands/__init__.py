"""Sub-commands of the tlfleet CLI (see cli.main)."""
