"""Recording a run: the run directory's files, written as the run goes.

* ``rundir`` — the one module that reads and writes the run directory's files;
* ``run_record`` — what ``summary.json`` and ``report.json`` hold, as typed records, and their
  schema versions; ``typed_json`` — those records to JSON and back;
* ``recorder`` — the tap on the bus that records frames, statuses and events;
* ``frame_merge`` — frames merged by sequence number across gaps (backfill);
* ``replay_dedup`` — which replayed agent events are already recorded;
* ``trust`` — what the recorder believes of a message's claimed source.
"""
