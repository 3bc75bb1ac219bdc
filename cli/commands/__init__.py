"""Sub-commands of the tlfleet CLI (see tlfleet.cli.main)."""
