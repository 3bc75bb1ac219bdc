"""A secured fleet as plain zenoh configuration: mutual TLS links and the router's access control.

Zenoh 1.10 (``DEFAULT_CONFIG.json5``; ``zenoh/src/net/routing/interceptor/access_control.rs``)
offers what the fleet needs, and this module only *produces configuration entries* for it, so the
same dictionaries can go into a :class:`~tlfleet.bus.transport.TransportConfig` (``extra``), a
``--zenoh-config`` file or a compose file:

* ``tls/<host>:<port>`` endpoints; ``transport/link/tls/root_ca_certificate`` is the fleet CA, the
  listening side presents ``listen_certificate``/``listen_private_key``, the connecting side
  ``connect_certificate``/``connect_private_key``, and ``enable_mtls`` makes the listener demand
  and verify a client certificate (a client without one, or with one from another CA, fails the
  handshake and never gets a session);
* ``access_control`` on the router: rules (message kinds × flows × key expressions), subjects
  (``cert_common_names``: the certificate's CN *is* the process identity — ``router``, ``sim``,
  ``coordinator``, ``robot3``…) and policies binding them; ``default_permission: "deny"``.

Every client talks through the router (docs/stack-notes.md §0), so the router's interceptors see
every message twice: *ingress* (from the sender's link) and *egress* (towards each receiver's link).
With ``default_permission: "deny"`` zenoh filters both flows, so each capability of a
:class:`Grant` allows the messages of both directions it needs:

=========  ====================================================  ============================
grant      ingress (from the process)                            egress (to the process)
=========  ====================================================  ============================
publish    ``put``                                               —
discover   —                                                     ``declare_subscriber``
subscribe  ``declare_subscriber``                                ``put``
serve      ``declare_queryable``, ``reply``                      ``query``
query      ``query``                                             ``reply``, ``declare_queryable``
find       —                                                     ``declare_queryable``
token      ``liveliness_token``                                  —
watch      ``declare_liveliness_subscriber``, ``liveliness_query``  ``liveliness_token``
=========  ====================================================  ============================

``discover`` exists because of zenoh's write-side filtering (measured on the 1.10 wheel): a
publisher sends only while it knows a matching subscriber, so it must receive the subscribers'
declarations *as declared* — the sim's ``robot/*/cmd``, the recorder's ``tlfleet/<fleet>/**`` —
and a rule on its own concrete key does not include those wildcards. It reveals which
subscriptions exist, never data: a ``put`` reaches a process only through its ``subscribe``
grant. ``find`` is the same for queries between peers: a querier linked straight to the
queryable's process (the peer layout of namespace hosts) learns it from its declaration *as
declared* — robot 4's ``robot/4/collab/*`` — which the querier's concrete key does not include;
through a router a client needs no declaration. It reveals which queryables exist, never a reply:
a query reaches a process only through the querier's ``query`` grant.

The scenario-specific grants (who may put, serve and query what) are computed by
:mod:`tlfleet.coordinator.security.policy`; the keys and certificates are written by
:mod:`tlfleet.coordinator.security.authority`. This module imports no zenoh and no cryptography:
certificate fingerprints are the SHA-256 of the DER bytes inside the PEM file.
"""

from __future__ import annotations

import base64
import hashlib
import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.transport import TransportConfig

CA_CERT = "ca.pem"
CA_KEY = "ca.key"
POLICY = "acl.json"
MANIFEST = "fleet.json"

# capability -> flow -> zenoh ACL message kinds (the table of the module docstring)
CAPABILITIES: dict[str, dict[str, tuple[str, ...]]] = {
    "publish": {"ingress": ("put",)},
    "discover": {"egress": ("declare_subscriber",)},
    "subscribe": {"ingress": ("declare_subscriber",), "egress": ("put",)},
    "serve": {"ingress": ("declare_queryable", "reply"), "egress": ("query",)},
    "query": {"ingress": ("query",), "egress": ("reply", "declare_queryable")},
    "find": {"egress": ("declare_queryable",)},
    "token": {"ingress": ("liveliness_token",)},
    "watch": {"ingress": ("declare_liveliness_subscriber", "liveliness_query"),
              "egress": ("liveliness_token",)},
}

_IDENTITY = re.compile(r"(router|sim|coordinator|robot[0-9]+)\Z")
_PEM = re.compile(rb"-----BEGIN CERTIFICATE-----\s*(.+?)\s*-----END CERTIFICATE-----", re.S)


class SecurityError(TlfleetError, ValueError):
    """A key directory, policy file or secured endpoint that cannot work (names file and field)."""


def identity(role: str, robot: int | None = None) -> str:
    """The certificate common name of a process: ``router``, ``sim``, ``coordinator`` or
    ``robot<id>``."""
    if role == "agent":
        if robot is None:
            raise SecurityError("an agent's identity needs its robot id")
        return f"robot{int(robot)}"
    if role not in ("router", "sim", "coordinator"):
        raise SecurityError(f"unknown process role {role!r}; expected router, sim, coordinator "
                            "or agent")
    return role


def check_identity(name: str) -> str:
    if not _IDENTITY.match(name):
        raise SecurityError(f"identity {name!r} is not one of router, sim, coordinator, "
                            "robot<id>")
    return name


# --------------------------------------------------------------------------- key directory

@dataclass(frozen=True)
class KeyDir:
    """The files of a key directory written by ``tlfleet keys``
    (:mod:`tlfleet.coordinator.security.authority`)."""

    path: Path

    @property
    def ca(self) -> Path:
        return self.path / CA_CERT

    @property
    def policy(self) -> Path:
        return self.path / POLICY

    def cert(self, name: str) -> Path:
        return self.path / f"{check_identity(name)}.pem"

    def key(self, name: str) -> Path:
        return self.path / f"{check_identity(name)}.key"

    def require(self, name: str) -> None:
        """Raise :class:`SecurityError` naming the first missing file of identity ``name``."""
        if not self.path.is_dir():
            raise SecurityError(f"{self.path}: no such key directory (create it with "
                                "`tlfleet keys SCENARIO --out DIR`)")
        for path in (self.ca, self.cert(name), self.key(name)):
            if not path.is_file():
                raise SecurityError(f"{path}: missing (identity {name!r}); the key directory "
                                    f"{self.path} was not written for this process")


def tls_entries(keydir: Path | KeyDir, name: str, *, listen: bool) -> dict[str, Any]:
    """The zenoh config entries (path → JSON value) of identity ``name``'s mutual-TLS links.

    ``listen``: the process accepts links (the router); it then also presents the same certificate
    when it connects (routers of several hosts). Paths are absolute, so the entries work from any
    working directory.
    """
    kd = keydir if isinstance(keydir, KeyDir) else KeyDir(Path(keydir))
    kd.require(name)
    cert, key = str(kd.cert(name).resolve()), str(kd.key(name).resolve())
    entries: dict[str, Any] = {
        "transport/link/tls/root_ca_certificate": str(kd.ca.resolve()),
        "transport/link/tls/enable_mtls": True,
        "transport/link/tls/connect_certificate": cert,
        "transport/link/tls/connect_private_key": key,
        "transport/link/tls/verify_name_on_connect": True,
        "transport/link/tls/close_link_on_expiration": True,
    }
    if listen:
        entries["transport/link/tls/listen_certificate"] = cert
        entries["transport/link/tls/listen_private_key"] = key
    return entries


def secure_endpoint(endpoint: str) -> str:
    """``tcp/HOST:PORT`` → ``tls/HOST:PORT`` (``tls/`` unchanged); any other protocol is refused:
    a secured fleet has no plain link."""
    proto, sep, rest = endpoint.partition("/")
    if not sep or not rest:
        raise SecurityError(f"endpoint {endpoint!r}: expected PROTOCOL/HOST:PORT")
    if proto in ("tcp", "tls"):
        return f"tls/{rest}"
    raise SecurityError(f"endpoint {endpoint!r}: a secured link is tls/… (or tcp/…, turned into "
                        f"tls/…), not {proto}/…")


def secure_transport(config: TransportConfig, keydir: Path, name: str) -> TransportConfig:
    """``config`` with every endpoint on TLS, the mutual-TLS entries of ``name`` and, for a
    router or a peer, the access-control policy of the key directory (``acl.json``).

    Every node that accepts links enforces the policy on what arrives over them: a peer too,
    since peers link to each other directly and a router never sees that traffic (measured
    with robot 2's certificate on a direct link to the simulator's peer: without the policy
    there, 20 of 20 puts on robot 1's command key arrived; with it, none, and 20 of 20 on its
    own key). A client links only to its router, which enforces it."""
    enforce = config.mode in ("router", "peer")
    kd = KeyDir(Path(keydir))
    extra = dict(config.extra)
    extra.update(tls_entries(kd, name, listen=config.mode == "router" or bool(config.listen)))
    if enforce:
        extra["access_control"] = load_policy(kd.policy)
    return replace(config, connect=tuple(secure_endpoint(e) for e in config.connect),
                   listen=tuple(secure_endpoint(e) for e in config.listen), extra=extra)


# --------------------------------------------------------------------------- access control

@dataclass(frozen=True)
class Grant:
    """What one identity may do, as key expressions per capability (module docstring table)."""

    identity: str
    publish: tuple[str, ...] = ()
    discover: tuple[str, ...] = ()
    subscribe: tuple[str, ...] = ()
    serve: tuple[str, ...] = ()
    query: tuple[str, ...] = ()
    find: tuple[str, ...] = ()
    token: tuple[str, ...] = ()
    watch: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        check_identity(self.identity)

    def capabilities(self) -> Iterable[tuple[str, tuple[str, ...]]]:
        for capability in CAPABILITIES:
            key_exprs = getattr(self, capability)
            if key_exprs:
                yield capability, key_exprs


def access_control(grants: Iterable[Grant]) -> dict[str, Any]:
    """The router's ``access_control`` block: one subject per identity (its certificate CN), one
    rule per (identity, capability, flow), one policy per identity; everything else denied."""
    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    seen: set[str] = set()
    for grant in grants:
        if grant.identity in seen:
            raise SecurityError(f"identity {grant.identity!r} granted twice")
        seen.add(grant.identity)
        subjects.append({"id": grant.identity, "cert_common_names": [grant.identity]})
        rule_ids = []
        for capability, key_exprs in grant.capabilities():
            for flow, messages in CAPABILITIES[capability].items():
                rule_id = f"{grant.identity}/{capability}/{flow}"
                rules.append({"id": rule_id, "permission": "allow", "flows": [flow],
                              "messages": list(messages), "key_exprs": list(key_exprs)})
                rule_ids.append(rule_id)
        if rule_ids:
            policies.append({"id": grant.identity, "rules": rule_ids,
                             "subjects": [grant.identity]})
    if not policies:
        raise SecurityError("an access-control policy needs at least one grant")
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": subjects, "policies": policies}


_BLOCK_FIELDS = ("enabled", "default_permission", "rules", "subjects", "policies")


def load_policy(path: Path) -> dict[str, Any]:
    """Read a policy file written by ``tlfleet keys`` (JSON: the ``access_control`` block) and
    check the fields zenoh refuses to start without."""
    try:
        block = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SecurityError(f"{path}: missing (the router's access-control policy; "
                            "`tlfleet keys` writes it)") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise SecurityError(f"{path}: not a JSON policy: {exc}") from None
    if not isinstance(block, dict):
        raise SecurityError(f"{path}: expected a JSON object (the access_control block)")
    for name in _BLOCK_FIELDS:
        if name not in block:
            raise SecurityError(f"{path}: field {name!r} missing")
    if block["enabled"] is not True or block["default_permission"] != "deny":
        raise SecurityError(f"{path}: expected enabled: true and default_permission: \"deny\", "
                            f"got {block['enabled']!r} and {block['default_permission']!r}")
    for name in ("rules", "subjects", "policies"):
        if not isinstance(block[name], list) or not block[name]:
            raise SecurityError(f"{path}: field {name!r}: expected a non-empty list")
    return block


# --------------------------------------------------------------------------- fingerprints

def fingerprint(cert: Path) -> str:
    """SHA-256 of a PEM certificate's DER bytes, as ``sha256:<hex>`` (what ``openssl x509
    -fingerprint -sha256`` shows, without the colons)."""
    match = _PEM.search(Path(cert).read_bytes())
    if match is None:
        raise SecurityError(f"{cert}: no PEM certificate in the file")
    der = base64.b64decode(b"".join(match.group(1).split()))
    return "sha256:" + hashlib.sha256(der).hexdigest()


def fingerprints(keydir: Path, names: Iterable[str]) -> dict[str, str]:
    """``{"ca": …, name: …}``: the fingerprints a secured run records in ``run.json``."""
    kd = KeyDir(Path(keydir))
    out = {"ca": fingerprint(kd.ca)}
    for name in names:
        out[name] = fingerprint(kd.cert(name))
    return out


def manifest(keydir: Path) -> Mapping[str, Any]:
    """The ``fleet.json`` of a key directory (fleet, identities, fingerprints)."""
    path = Path(keydir) / MANIFEST
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SecurityError(f"{path}: missing (`tlfleet keys` writes it)") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise SecurityError(f"{path}: not JSON: {exc}") from None
