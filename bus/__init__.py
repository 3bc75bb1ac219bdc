"""The ground floor every tlfleet process stands on (docs/architecture.md §4).

* ``errors`` — the error hierarchy every layer raises (stdlib only);
* ``protocol`` — the wire protocol: typed messages, their one MessagePack codec, key expressions;
* ``transport`` — the :class:`~tlfleet.bus.transport.Transport` interface the processes talk
  through, and key-expression matching; ``fake`` — its in-memory stand-in for tests;
  ``signals`` — SIGINT/SIGTERM handling shared by every process;
* ``zenoh`` — the Eclipse Zenoh implementation (the only package importing zenoh).

Nothing here imports any other tlfleet package.
"""
