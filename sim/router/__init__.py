"""The zenoh router process (``tlfleet router``): the fleet's meeting point.

A process beside the simulator, not part of the bus: ``process`` opens a router session through
the bus and keeps it until SIGINT/SIGTERM; ``denials`` turns zenoh's access-control trace lines
into one warning per denied key.
"""
