"""A fleet's security material.

* ``policy`` — the access-control policy: who may put, subscribe, serve, query what;
* ``authority`` — ``tlfleet keys``: the fleet's certificate authority, one key pair and
  certificate per process, and the router's policy file.
"""
