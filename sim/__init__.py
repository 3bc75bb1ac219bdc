"""The pymunk simulator process: robot hardware and motion capture (architecture.md §1)."""
