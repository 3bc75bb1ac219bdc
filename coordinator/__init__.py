"""The coordinator: command line, launch, supervision, recording and reports (architecture.md §1)."""
