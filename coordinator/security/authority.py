"""``tlfleet keys SCENARIO --out DIR``: the fleet's certificate authority, one key pair and
certificate per process, and the router's access-control policy.

The directory holds

==========================  ===================================================================
``ca.pem``, ``ca.key``      the fleet CA (self-signed, ECDSA P-256); ``ca.key`` signs, keep it off
                            the robots (a process needs only ``ca.pem`` and its own pair)
``<id>.pem``, ``<id>.key``  one per process, CN = its identity (``router``, ``sim``,
                            ``coordinator``, ``robot<id>``), signed by the CA, for server and
                            client authentication; the router's also names ``localhost``,
                            ``127.0.0.1``, ``::1`` and every ``--host`` (the names clients
                            connect to: zenoh verifies the server name)
``acl.json``                the router's ``access_control`` block
(:mod:`tlfleet.coordinator.security.policy`,
                            :func:`tlfleet.bus.zenoh.security.access_control`)
``fleet.json``              fleet, identities and SHA-256 fingerprints
==========================  ===================================================================

Private keys are written with mode 0600 (``O_CREAT`` with that mode: never readable by others,
not even for a moment); nothing is overwritten unless ``force``. Uses the ``cryptography``
package (no ``openssl`` shell-outs).
"""

from __future__ import annotations

import datetime
import ipaddress
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
from tlfleet.agent.model import Scenario
from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.zenoh.security import (
    CA_CERT,
    CA_KEY,
    MANIFEST,
    POLICY,
    KeyDir,
    SecurityError,
    access_control,
    fingerprint,
    load_policy,
    manifest,
)
from tlfleet.coordinator.security.policy import fleet_grants, identities

ROUTER_NAMES = ("localhost", "127.0.0.1", "::1")
CA_DAYS = 3650
KEY_MODE = 0o600


class KeysError(TlfleetError, ValueError):
    """Keys that cannot be written (existing files without ``--force``, a bad host name)."""


@dataclass(frozen=True)
class KeySet:
    """What :func:`write_keys` wrote."""

    path: Path
    identities: tuple[str, ...]
    fingerprints: dict[str, str]
    files: tuple[Path, ...]


def _name(common_name: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.ORGANIZATION_NAME, "tlfleet"),
                      x509.NameAttribute(NameOID.COMMON_NAME, common_name)])


def _general_name(host: str) -> x509.GeneralName:
    try:
        return x509.IPAddress(ipaddress.ip_address(host))
    except ValueError:
        pass
    if not host or any(c.isspace() or c in "/:" for c in host):
        raise KeysError(f"--host {host!r}: expected a DNS name or an IP address")
    return x509.DNSName(host)


def _key_usage(*, ca: bool) -> x509.KeyUsage:
    return x509.KeyUsage(digital_signature=True, content_commitment=False, key_encipherment=False,
                         data_encipherment=False, key_agreement=False, key_cert_sign=ca,
                         crl_sign=ca, encipher_only=False, decipher_only=False)


def _write(path: Path, data: bytes, mode: int) -> None:
    """Write ``data`` to ``path`` created with ``mode`` (existing files were checked before)."""
    if path.exists():
        path.unlink()
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, mode)
    with os.fdopen(fd, "wb") as handle:
        handle.write(data)
    os.chmod(path, mode)  # the umask may have cleared bits of a public file's 0644


def _pem_key(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())


def planned_files(out: Path, names: Sequence[str]) -> tuple[Path, ...]:
    files = [out / CA_CERT, out / CA_KEY]
    for name in names:
        files += [out / f"{name}.pem", out / f"{name}.key"]
    return (*files, out / POLICY, out / MANIFEST)


def write_keys(scenario: Scenario, out: Path, *, force: bool = False,
               hosts: Sequence[str] = (), days: int = 365, mesh: bool = False,
               addresses: Mapping[str, Sequence[str]] | None = None,
               now: datetime.datetime | None = None) -> KeySet:
    """Write the CA, every process's key and certificate, ``acl.json`` and ``fleet.json``.

    ``hosts``: extra names of the router's certificate (multi-host fleets); ``days``: validity
    of the process certificates; ``mesh``: the policy lets routers forward to each other
    (several routers, :func:`tlfleet.coordinator.security.policy.fleet_grants`); ``addresses``:
    extra names of a process's own certificate (``{"robot3": ["10.251.7.15"]}``: a peer that others
    connect to by address, the peer layout of :mod:`tlfleet.coordinator.launch.netns_hosts`). Raises
    :class:`KeysError` before writing anything when a file exists and ``force`` is false.
    """
    if days < 1:
        raise KeysError(f"--days must be at least 1, got {days}")
    out = Path(out)
    names = identities(scenario)
    files = planned_files(out, names)
    existing = [p for p in files if p.exists()]
    if existing and not force:
        shown = ", ".join(str(p) for p in existing[:3]) + (" …" if len(existing) > 3 else "")
        raise KeysError(f"{out}: {len(existing)} key file(s) exist ({shown}); "
                        "use --force to overwrite")
    router_names = [_general_name(h) for h in dict.fromkeys((*ROUTER_NAMES, *hosts))]
    policy = access_control(fleet_grants(scenario, mesh=mesh))
    out.mkdir(parents=True, exist_ok=True)
    now = now or datetime.datetime.now(datetime.UTC)
    start = now - datetime.timedelta(minutes=5)  # tolerate small clock skew between hosts

    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_subject = _name(f"tlfleet {scenario.fleet} CA")
    ca_cert = (x509.CertificateBuilder().subject_name(ca_subject).issuer_name(ca_subject)
               .public_key(ca_key.public_key()).serial_number(x509.random_serial_number())
               .not_valid_before(start).not_valid_after(now + datetime.timedelta(days=CA_DAYS))
               .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
               .add_extension(_key_usage(ca=True), critical=True)
               .add_extension(x509.SubjectKeyIdentifier.from_public_key(ca_key.public_key()),
                              critical=False)
               .sign(ca_key, hashes.SHA256()))
    _write(out / CA_KEY, _pem_key(ca_key), KEY_MODE)
    _write(out / CA_CERT, ca_cert.public_bytes(serialization.Encoding.PEM), 0o644)
    for name in names:
        key = ec.generate_private_key(ec.SECP256R1())
        alt = router_names if name == "router" else [
            x509.DNSName(name), *(_general_name(a) for a in (addresses or {}).get(name, ()))]
        cert = (x509.CertificateBuilder().subject_name(_name(name)).issuer_name(ca_subject)
                .public_key(key.public_key()).serial_number(x509.random_serial_number())
                .not_valid_before(start).not_valid_after(now + datetime.timedelta(days=days))
                .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
                .add_extension(_key_usage(ca=False), critical=True)
                .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                                      ExtendedKeyUsageOID.CLIENT_AUTH]),
                               critical=False)
                .add_extension(x509.SubjectAlternativeName(alt), critical=False)
                .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(
                    ca_key.public_key()), critical=False)
                .sign(ca_key, hashes.SHA256()))
        _write(out / f"{name}.key", _pem_key(key), KEY_MODE)
        _write(out / f"{name}.pem", cert.public_bytes(serialization.Encoding.PEM), 0o644)
    _write(out / POLICY, (json.dumps(policy, indent=1) + "\n").encode(), 0o644)
    prints = {"ca": fingerprint(out / CA_CERT)}
    prints.update({name: fingerprint(out / f"{name}.pem") for name in names})
    info = {"fleet": scenario.fleet, "scenario": scenario.name, "identities": list(names),
            "router_names": list(dict.fromkeys((*ROUTER_NAMES, *hosts))),
            "created": now.strftime("%Y-%m-%dT%H:%M:%SZ"), "days": days,
            "fingerprints": prints}
    _write(out / MANIFEST, (json.dumps(info, indent=1) + "\n").encode(), 0o644)
    return KeySet(out, names, prints, files)


def check_keys(scenario: Scenario, keydir: Path, names: Sequence[str] | None = None) -> None:
    """Raise :class:`tlfleet.bus.zenoh.security.SecurityError` unless ``keydir`` holds the CA
    and the key and certificate of each identity of ``names`` (default: every process of
    ``scenario``, as ``tlfleet run`` starts them all) — and the router's access policy when the
    router is among them. Least privilege: ``tlfleet supervise`` asks only for
    ``("coordinator",)``, so the coordinator's machine needs ``ca.pem`` and its own pair, no
    other process's private key. ``fleet.json``, where present, must name the scenario's fleet."""
    kd = KeyDir(Path(keydir))
    for name in identities(scenario) if names is None else names:
        kd.require(name)
    if (kd.path / MANIFEST).is_file():
        info = manifest(kd.path)
        if info.get("fleet") != scenario.fleet:
            raise SecurityError(f"{kd.path / MANIFEST}: keys of fleet {info.get('fleet')!r}, "
                                f"the scenario's fleet is {scenario.fleet!r}")
    if names is None or "router" in names:
        load_policy(kd.policy)
