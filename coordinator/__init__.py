"""The coordinator: command line, launch, supervision, recording, reports (architecture.md §1)."""
