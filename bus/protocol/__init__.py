"""Messages, codec and key expressions (architecture.md §2). Stdlib + msgpack only."""
