"""The coordinator: one whole run of a fleet, from validation to the report.

docs/architecture.md §1 and §6 describe the run.

Entry points, on top: ``run`` (``tlfleet run``: launch, supervise, record, report), ``run_hosts``
(the same on network-namespace hosts), ``supervise`` (``tlfleet supervise``: the coordinator's
own part, joining a fleet started elsewhere; ``run`` uses it too), ``compose`` (``tlfleet
compose``: the docker compose file of a fleet). Below them, by what they do: ``launch``,
``record``, ``live`` (supervision and verdict), ``faults``, ``report``, ``security``.
"""
