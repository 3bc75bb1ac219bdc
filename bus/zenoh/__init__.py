"""The Eclipse Zenoh implementation of the bus: the only package that imports zenoh.

* ``transport`` — :class:`ZenohTransport`, the :class:`tlfleet.bus.transport.Transport` over a
  zenoh session (the only ``import zenoh`` of the tree);
* ``config`` — a user's zenohd-style config file merged under tlfleet's own settings;
* ``security`` — mutual TLS and the router's access-control policy as zenoh config.
"""
