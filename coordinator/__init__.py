"""The coordinator: launch, supervision, recording, summary, report, figures and the rerun view
(architecture.md §1, §6); the command line that drives it is ``cli``."""
