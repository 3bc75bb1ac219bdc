"""Keys, certificates, the generated access-control policy and the denial-log parser (no process).

The policy is checked as zenoh reads it: a message kind on a key is allowed for a subject iff a
rule of that subject's policy for that flow lists the kind and one of its key expressions
*includes* the key (for concrete keys: matches it, ``tlfleet.bus.transport.key_matches``).
"""

from __future__ import annotations

import json
import stat

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
from security_helpers import ROOT, SCENARIO1
from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.protocol import keys
from tlfleet.bus.transport import TransportConfig, key_matches
from tlfleet.bus.zenoh.security import (
    CAPABILITIES,
    Grant,
    KeyDir,
    SecurityError,
    access_control,
    fingerprint,
    load_policy,
    secure_endpoint,
    secure_transport,
    tls_entries,
)
from tlfleet.cli.main import main as cli_main
from tlfleet.coordinator.security.authority import KeysError, check_keys, write_keys
from tlfleet.coordinator.security.policy import coupled_robots, fleet_grants, identities
from tlfleet.sim.router.denials import Caching, Decision, DenialFilter, NoSubject, Other, parse_line

F = "scenario1"


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(SCENARIO1)


@pytest.fixture(scope="module")
def keydir(scenario, tmp_path_factory):
    out = tmp_path_factory.mktemp("keys")
    write_keys(scenario, out, hosts=("fleet.example", "10.0.0.7"))
    return KeyDir(out)


def load_cert(path):
    return x509.load_pem_x509_certificate(path.read_bytes())


# --------------------------------------------------------------------------- keys

def test_keys_one_certificate_per_process_cn_is_the_identity(keydir, scenario):
    names = identities(scenario)
    assert names == ("router", "sim", "coordinator", "robot1", "robot2", "robot3", "robot4",
                     "robot5")
    ca = load_cert(keydir.ca)
    for name in names:
        cert = load_cert(keydir.cert(name))
        cn = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value
        assert cn == name
        cert.verify_directly_issued_by(ca)  # raises if not signed by the fleet CA
        eku = cert.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
        assert {ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH} <= set(eku)
        assert not cert.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    assert ca.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    san = load_cert(keydir.cert("router")).extensions.get_extension_for_class(
        x509.SubjectAlternativeName).value
    assert set(san.get_values_for_type(x509.DNSName)) == {"localhost", "fleet.example"}
    assert {str(a) for a in san.get_values_for_type(x509.IPAddress)} == {"127.0.0.1", "::1",
                                                                          "10.0.0.7"}


def test_private_keys_are_mode_0600_certificates_public(keydir, scenario):
    for name in identities(scenario):
        assert stat.S_IMODE(keydir.key(name).stat().st_mode) == 0o600, name
        assert stat.S_IMODE(keydir.cert(name).stat().st_mode) == 0o644, name
    assert stat.S_IMODE((keydir.path / "ca.key").stat().st_mode) == 0o600


def test_keys_refuse_to_overwrite_unless_forced(scenario, tmp_path, capsys):
    write_keys(scenario, tmp_path)
    before = (tmp_path / "robot3.pem").read_bytes()
    with pytest.raises(KeysError, match=r"exist .*use --force"):
        write_keys(scenario, tmp_path)
    assert (tmp_path / "robot3.pem").read_bytes() == before
    assert cli_main(["keys", str(SCENARIO1), "--out", str(tmp_path)]) == 1
    assert "use --force" in capsys.readouterr().err
    assert cli_main(["keys", str(SCENARIO1), "--out", str(tmp_path), "--force"]) == 0
    assert (tmp_path / "robot3.pem").read_bytes() != before
    assert stat.S_IMODE((tmp_path / "robot3.key").stat().st_mode) == 0o600


def test_bad_host_is_a_clear_error(scenario, tmp_path):
    with pytest.raises(KeysError, match="--host 'a/b'"):
        write_keys(scenario, tmp_path, hosts=("a/b",))
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_fingerprint_is_the_sha256_of_the_der_certificate(keydir):
    cert = load_cert(keydir.cert("robot3"))
    assert fingerprint(keydir.cert("robot3")) == "sha256:" + cert.fingerprint(
        hashes.SHA256()).hex()
    manifest = json.loads((keydir.path / "fleet.json").read_text())
    assert manifest["fleet"] == F
    assert manifest["fingerprints"]["robot3"] == fingerprint(keydir.cert("robot3"))


def test_check_keys_names_what_is_wrong(scenario, keydir, tmp_path):
    check_keys(scenario, keydir.path)
    other = load_scenario(ROOT / "tests" / "system" / "two_robots.toml")
    write_keys(other, tmp_path / "two")
    with pytest.raises(SecurityError, match=r"(sim|robot3)\.pem: missing"):
        check_keys(scenario, tmp_path / "two")
    with pytest.raises(SecurityError, match="no such key directory"):
        check_keys(scenario, tmp_path / "nowhere")


# --------------------------------------------------------------------------- config entries

def test_tls_entries_and_secured_endpoints(keydir):
    client = secure_transport(TransportConfig(mode="client", connect=("tcp/127.0.0.1:7447",)),
                              keydir.path, "robot3")
    assert client.connect == ("tls/127.0.0.1:7447",)
    assert client.extra["transport/link/tls/enable_mtls"] is True
    assert client.extra["transport/link/tls/connect_certificate"].endswith("/robot3.pem")
    assert "access_control" not in client.extra
    assert "transport/link/tls/listen_certificate" not in client.extra
    router = secure_transport(TransportConfig(mode="router", listen=("tcp/127.0.0.1:7447",)),
                              keydir.path, "router")
    assert router.listen == ("tls/127.0.0.1:7447",)
    assert router.extra["transport/link/tls/listen_private_key"].endswith("/router.key")
    assert router.extra["access_control"] == load_policy(keydir.policy)
    assert tls_entries(keydir, "sim", listen=False)["transport/link/tls/root_ca_certificate"] \
        == str(keydir.ca.resolve())
    with pytest.raises(SecurityError, match="not udp"):
        secure_endpoint("udp/127.0.0.1:7447")
    with pytest.raises(SecurityError, match=r"robot9\.pem: missing"):
        tls_entries(keydir, "robot9", listen=False)
    with pytest.raises(SecurityError, match="identity 'mallory'"):
        tls_entries(keydir, "mallory", listen=False)


def test_load_policy_rejects_a_permissive_or_broken_file(tmp_path):
    path = tmp_path / "acl.json"
    path.write_text("{not json")
    with pytest.raises(SecurityError, match=r"acl\.json: not a JSON policy"):
        load_policy(path)
    good = access_control([Grant("sim", publish=("a",))])
    path.write_text(json.dumps({**good, "default_permission": "allow"}))
    with pytest.raises(SecurityError, match="default_permission"):
        load_policy(path)
    path.write_text(json.dumps({k: v for k, v in good.items() if k != "subjects"}))
    with pytest.raises(SecurityError, match="field 'subjects' missing"):
        load_policy(path)


# --------------------------------------------------------------------------- the policy

def allowed(block, who: str, flow: str, message: str, key: str) -> bool:
    rules = {r["id"]: r for r in block["rules"]}
    subjects = {s["id"] for s in block["subjects"] if who in s["cert_common_names"]}
    for policy in block["policies"]:
        if not subjects & set(policy["subjects"]):
            continue
        for rule_id in policy["rules"]:
            rule = rules[rule_id]
            if (rule["permission"] == "allow" and flow in rule["flows"]
                    and message in rule["messages"]
                    and any(key_matches(expr, key) for expr in rule["key_exprs"])):
                return True
    return block["default_permission"] == "allow"


@pytest.fixture(scope="module")
def policy(scenario):
    return access_control(fleet_grants(scenario))


def test_scenario1_coupling(scenario):
    assert coupled_robots(scenario) == {3: (4,), 4: (3, 5), 5: (4,)}


@pytest.mark.parametrize("key, ok", [
    (keys.cmd(F, 3), True), (keys.status(F, 3), True), (keys.event(F, "agent", 3), True),
    (keys.cmd(F, 4), False), (keys.status(F, 4), False), (keys.control(F), False),
    (keys.event(F, "agent", 4), False), (keys.event(F, "sim", 0), False),
    (keys.event(F, "coordinator", 0), False),
    (keys.mocap(F), False), (keys.clock(F), False), (keys.collab_from(F, 4, 3), False),
])
def test_robot3_puts_only_its_own_keys(policy, key, ok):
    assert allowed(policy, "robot3", "ingress", "put", key) is ok


def test_robot3_serves_only_its_collab_and_queries_only_coupled_robots(policy):
    """Robot 3 serves its ``collab/*`` and queries robot 4 on ``robot/4/collab/3`` only: the key
    names the sender, so it cannot speak as robot 5 (robot 4 checks the message's sender)."""
    served = keys.collab_all(F, 3)
    assert allowed(policy, "robot3", "ingress", "declare_queryable", served)
    assert allowed(policy, "robot3", "ingress", "reply", keys.collab_from(F, 3, 4))
    assert not allowed(policy, "robot3", "ingress", "declare_queryable", keys.collab_all(F, 4))
    assert not allowed(policy, "robot3", "ingress", "reply", keys.collab_from(F, 4, 3))
    assert allowed(policy, "robot3", "ingress", "query", keys.collab_from(F, 4, 3))
    assert not allowed(policy, "robot3", "ingress", "query", keys.collab_from(F, 4, 5))
    assert not allowed(policy, "robot3", "ingress", "query", keys.collab_from(F, 5, 3))  # uncoupled
    assert allowed(policy, "robot3", "egress", "query", keys.collab_from(F, 3, 4))
    assert not allowed(policy, "robot3", "egress", "query", keys.collab_from(F, 4, 5))
    assert not allowed(policy, "robot1", "ingress", "declare_queryable", keys.collab_all(F, 1))
    # on a direct peer link robot 3 learns robot 4's queryable as declared, no one else's
    assert allowed(policy, "robot3", "egress", "declare_queryable", keys.collab_all(F, 4))
    assert not allowed(policy, "robot3", "egress", "declare_queryable", keys.collab_all(F, 5))


def test_robot3_token_and_subscriptions(policy):
    assert allowed(policy, "robot3", "ingress", "liveliness_token", keys.alive(F, "agent", 3))
    assert not allowed(policy, "robot3", "ingress", "liveliness_token",
                       keys.alive(F, "agent", 4))
    assert not allowed(policy, "robot3", "ingress", "liveliness_token", keys.alive(F, "sim", 0))
    for key in (keys.mocap(F), keys.clock(F), keys.control(F)):
        assert allowed(policy, "robot3", "ingress", "declare_subscriber", key)
        assert allowed(policy, "robot3", "egress", "put", key)
    for key in (keys.cmd(F, 4), keys.status(F, 4), keys.event(F, "agent", 4)):
        assert not allowed(policy, "robot3", "ingress", "declare_subscriber", key)
        assert not allowed(policy, "robot3", "egress", "put", key)


def test_sim_and_coordinator(policy):
    for key in (keys.mocap(F), keys.clock(F), keys.event(F, "sim", 0)):
        assert allowed(policy, "sim", "ingress", "put", key)
    for key in (keys.event(F, "agent", 3), keys.event(F, "coordinator", 0)):
        assert not allowed(policy, "sim", "ingress", "put", key)
    assert allowed(policy, "coordinator", "ingress", "put", keys.event(F, "coordinator", 0))
    assert not allowed(policy, "coordinator", "ingress", "put", keys.event(F, "sim", 0))
    assert not allowed(policy, "sim", "ingress", "put", keys.cmd(F, 3))
    assert not allowed(policy, "sim", "ingress", "put", keys.control(F))
    assert allowed(policy, "sim", "egress", "put", keys.cmd(F, 4))
    assert allowed(policy, "coordinator", "ingress", "put", keys.control(F))
    assert not allowed(policy, "coordinator", "ingress", "put", keys.cmd(F, 3))
    assert not allowed(policy, "coordinator", "ingress", "put", keys.mocap(F))
    for key in (keys.cmd(F, 3), keys.status(F, 5), keys.mocap(F), keys.event(F, "sim", 0),
                keys.event(F, "agent", 3)):
        assert allowed(policy, "coordinator", "egress", "put", key)
    assert not allowed(policy, "router", "ingress", "put", keys.control(F))
    assert not allowed(policy, "mallory", "ingress", "put", keys.event(F, "sim", 0))


def test_only_the_sim_serves_the_backfill_and_only_the_coordinator_asks_for_it(policy):
    """``sim/backfill`` (the frames a recorder missed during a link cut)."""
    key = keys.sim_backfill(F)
    assert allowed(policy, "sim", "ingress", "declare_queryable", key)
    assert allowed(policy, "sim", "ingress", "reply", key)
    assert allowed(policy, "sim", "egress", "query", key)
    assert allowed(policy, "coordinator", "ingress", "query", key)
    assert allowed(policy, "coordinator", "egress", "reply", key)
    for who in ("robot3", "coordinator"):  # nobody else answers in the sim's name
        assert not allowed(policy, who, "ingress", "declare_queryable", key)
        assert not allowed(policy, who, "ingress", "reply", key)
    assert not allowed(policy, "robot3", "ingress", "query", key)
    assert not allowed(policy, "sim", "ingress", "query", key)


def test_a_router_mesh_lets_the_routers_forward_everything_of_the_fleet_only():
    scenario = load_scenario(SCENARIO1)
    mesh = access_control(fleet_grants(scenario, mesh=True))
    for flow, message, key in (("ingress", "put", keys.control(F)),
                               ("egress", "put", keys.cmd(F, 3)),
                               ("ingress", "query", keys.collab_from(F, 4, 3)),
                               ("ingress", "liveliness_token", keys.alive(F, "agent", 3))):
        assert allowed(mesh, "router", flow, message, key)
    assert not allowed(mesh, "router", "ingress", "put", "tlfleet/otherfleet/control")
    single = access_control(fleet_grants(scenario))
    assert {s["id"] for s in mesh["subjects"]} - {s["id"] for s in single["subjects"]} == \
        {"router"}


def test_every_rule_uses_known_message_kinds(policy):
    kinds = {m for flows in CAPABILITIES.values() for ms in flows.values() for m in ms}
    assert kinds <= {"put", "delete", "declare_subscriber", "query", "reply",
                     "declare_queryable", "liveliness_token", "liveliness_query",
                     "declare_liveliness_subscriber"}
    assert {m for r in policy["rules"] for m in r["messages"]} <= kinds
    assert len({r["id"] for r in policy["rules"]}) == len(policy["rules"])


# --------------------------------------------------------------------------- denial log

def zline(thread: str, body: str) -> str:
    """A line as zenoh 1.10's log subscriber writes it (with its ANSI colours)."""
    return (f"\x1b[2m2026-12-01T17:33:52.502530Z\x1b[0m \x1b[35mTRACE\x1b[0m rx-1 "
            f"ThreadId({thread}) \x1b[2mzenoh::net::routing::interceptor::access_control"
            f"\x1b[0m\x1b[2m:\x1b[0m {body}\n")


ZID = "c4ffbd1a9856c4b8ecdbb0e44f78ed0c"
SUBJ = f"{ZID} on Interface(lo)+CertCommonName(robot3)+Transport(Tls)+{ZID}"


def test_parse_line_reads_zenoh_110_acl_lines():
    assert parse_line(zline("09", "ACL (egress): caching permissions for "
                                  "`tlfleet/f/robot/4/collab` ...")) == \
        Caching("09", "tlfleet/f/robot/4/collab")
    assert parse_line(zline("09", f"{SUBJ} is unauthorized to Put (ingress) on "
                                  "tlfleet/f/robot/4/cmd")) == \
        Decision("09", False, ZID, "robot3", False, "Put (ingress)", "tlfleet/f/robot/4/cmd")
    assert parse_line(zline("08", f"Using cached result: {ZID} is authorized to Declare "
                                  "Subscriber (ingress) on tlfleet/f/event")) == \
        Decision("08", True, ZID, None, True, "Declare Subscriber (ingress)", "tlfleet/f/event")
    assert parse_line(zline("08", f"{ZID} did not match any configured ACL subject. Default "
                                  "permission `Deny` will be applied on all messages")) == \
        NoSubject(ZID)
    warn = parse_line("\x1b[2m2026\x1b[0m \x1b[33m WARN\x1b[0m acc-0 ThreadId(05) "
                      "zenoh_link_tls::unicast: invalid peer certificate: BadSignature.")
    assert isinstance(warn, Other) and warn.important
    assert not parse_line("2026 INFO ThreadId(01) zenoh::net::runtime: Using ZID: 1").important


@pytest.mark.parametrize("fast", [False, True])
def test_denial_filter_drops_cache_lines_and_reports_each_denial_once(fast):
    f = DenialFilter()
    feed = f.feed_raw if fast else (lambda line: f.feed(parse_line(line)))
    out = [feed(line) for line in (
        zline("09", "ACL (ingress): caching permissions for `tlfleet/f/robot/3/cmd` ..."),
        zline("09", f"{SUBJ} is authorized to Put (ingress) on tlfleet/f/robot/3/cmd"),
        zline("09", f"{SUBJ} is unauthorized to Query (ingress) on tlfleet/f/robot/3/cmd"),
        zline("09", "ACL (ingress): caching permissions for `tlfleet/f/robot/4/cmd` ..."),
        zline("09", f"{SUBJ} is unauthorized to Put (ingress) on tlfleet/f/robot/4/cmd"),
        zline("08", f"Using cached result: {ZID} is unauthorized to Put (ingress) on "
                    "tlfleet/f/robot/4/cmd"),
        zline("08", f"Using cached result: {ZID} is unauthorized to Put (ingress) on "
                    "tlfleet/f/robot/4/cmd"),
        zline("08", f"Using cached result: {ZID} is authorized to Put (ingress) on "
                    "tlfleet/f/robot/3/cmd"),
        zline("09", "ACL (ingress): caching permissions for `tlfleet/f/event` ..."),
        zline("09", f"{SUBJ} is authorized to Put (ingress) on tlfleet/f/event"),
        zline("09", f"{SUBJ} is unauthorized to Query (ingress) on tlfleet/f/event"),
        zline("09", f"{SUBJ} is unauthorized to Put (ingress) on tlfleet/f/control"),
    )]
    assert [m for m in out if m] == [
        "ACL denied: robot3 Put (ingress) on tlfleet/f/robot/4/cmd",
        "ACL denied: robot3 Put (ingress) on tlfleet/f/control"]
    assert f.denied == {("robot3", "Put (ingress)", "tlfleet/f/robot/4/cmd"): 2,
                        ("robot3", "Put (ingress)", "tlfleet/f/control"): 1}
    assert f.lines == 12


def test_ltl_robots_read_only_their_decimated_frames(policy):
    """Robot 1 (LTL, divider 20, phase 0) subscribes mocap_every/20/0 instead of
    mocap, robot 2 (LTL, phase 10) mocap_every/20/10; the sim publishes both; an STL robot
    (divider 1) keeps mocap."""
    every, other = keys.mocap_every(F, 20, 0), keys.mocap_every(F, 20, 10)
    assert allowed(policy, "sim", "ingress", "put", every)
    assert allowed(policy, "sim", "ingress", "put", other)
    assert allowed(policy, "robot1", "ingress", "declare_subscriber", every)
    assert allowed(policy, "robot1", "egress", "put", every)
    assert allowed(policy, "robot2", "ingress", "declare_subscriber", other)
    assert not allowed(policy, "robot1", "ingress", "declare_subscriber", other)
    assert not allowed(policy, "robot2", "ingress", "declare_subscriber", every)
    assert not allowed(policy, "robot1", "ingress", "declare_subscriber", keys.mocap(F))
    assert not allowed(policy, "robot1", "ingress", "put", every)
    assert not allowed(policy, "robot3", "ingress", "declare_subscriber", every)
    assert not allowed(policy, "sim", "ingress", "put", keys.mocap_every(F, 7))
