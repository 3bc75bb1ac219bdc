"""The ``tlfleet`` command line: thin wrappers over every process and tool (architecture.md §4).

``tlfleet.cli.main`` dispatches to one module per sub-command in ``tlfleet.cli.commands``; each
turns its flags into the typed configuration of the process or tool it starts (``SimConfig``,
``AgentConfig``,
``RunConfig``, …) and calls that package's ``main(config)``. Nothing below imports this package.
"""
