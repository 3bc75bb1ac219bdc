"""Supervising a running fleet and judging it.

* ``supervisor`` — readiness, start, deaths and the end of the run;
* ``health`` — agents that fall silent (frozen, partitioned) and their recovery;
* ``verdict`` — the run's verdict (clean, degraded, failed, interrupted) and its exit code.
"""
