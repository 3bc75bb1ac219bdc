"""Recording a run: the run directory's files, written as the run goes.

* ``rundir`` — the one module that reads and writes the run directory's files;
* ``recorder`` — the tap on the bus that records frames, statuses and events;
* ``frame_merge`` — frames merged by sequence number across gaps (backfill);
* ``replay_dedup`` — which replayed agent events are already recorded;
* ``trust`` — what the recorder believes of a message's claimed source.
"""
