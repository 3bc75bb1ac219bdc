"""Starting and stopping a run's processes.

* ``processes`` — child processes in their own process groups, stopped by group;
* ``cleanup`` — exception-safe, time-bounded clean-up steps;
* ``netns_hosts`` — network namespaces as stand-in hosts and the fleet's placement on them.
"""
