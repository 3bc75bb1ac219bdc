"""``--zenoh-config FILE.json5``: the file under tlfleet's own settings; a file
zenoh refuses is rejected naming the file and the key."""

from __future__ import annotations

import subprocess
import sys

import pytest
from tlfleet.bus.transport import TransportConfig
from tlfleet.bus.zenoh.config import ZenohConfigError, leaves, parse_json5
from tlfleet.bus.zenoh.transport import ZenohTransport


def config_of(tmp_path, text: str, **kwargs):
    path = tmp_path / "zenoh.json5"
    path.write_text(text)
    return path, ZenohTransport.zenoh_config(TransportConfig(zenoh_config=path, **kwargs))


def test_parse_json5_reads_comments_unquoted_keys_single_quotes_trailing_commas():
    text = """{
      // a comment
      mode: 'peer', /* another */
      transport: { link: { tx: { lease: 3000, }, }, },
      connect: { endpoints: ["tcp/10.0.0.1:7447",], },
      scouting: { multicast: { enabled: false } },
    }"""
    assert parse_json5(text) == {"mode": "peer", "transport": {"link": {"tx": {"lease": 3000}}},
                                 "connect": {"endpoints": ["tcp/10.0.0.1:7447"]},
                                 "scouting": {"multicast": {"enabled": False}}}
    assert dict(leaves(parse_json5(text)))["transport/link/tx/lease"] == 3000


def test_the_file_is_merged_under_tlfleets_settings(tmp_path):
    _, c = config_of(tmp_path, """{ mode: "peer", transport: { link: { tx: { lease: 3000 } } },
                                    scouting: { multicast: { enabled: true } },
                                    connect: { endpoints: ["tcp/127.0.0.1:7999"] } }""")
    assert c.get_json("transport/link/tx/lease") == "3000"  # the file's own setting stays
    assert c.get_json("mode") == '"client"'  # tlfleet's mode wins
    assert c.get_json("scouting/multicast/enabled") == "false"  # and its scouting rule
    assert c.get_json("connect/endpoints") == '["tcp/127.0.0.1:7999"]'  # no flag: the file's
    assert c.get_json("listen/endpoints") == "[]"  # never zenoh's all-interfaces default


def test_endpoint_flags_replace_the_files_endpoints(tmp_path):
    _, c = config_of(tmp_path, '{ connect: { endpoints: ["tcp/127.0.0.1:7999"] } }',
                     connect=("tcp/127.0.0.1:7000",), lease_ms=1500)
    assert c.get_json("connect/endpoints") == '["tcp/127.0.0.1:7000"]'
    assert c.get_json("transport/link/tx/lease") == "1500"
    # a blocked send queue closes its link as soon as a silent link is (1500 ms, in µs)
    assert c.get_json("transport/link/tx/queue/congestion_control/block/wait_before_close") \
        == "1500000"


@pytest.mark.parametrize(("text", "key", "reason"), [
    ("{ scouting: { bogus_key: 3 } }", "scouting/bogus_key", "unknown field `bogus_key`"),
    ('{ transport: { link: { tx: { lease: "soon" } } } }', "transport/link/tx/lease",
     "error parsing number"),
    ("{ transport: { shared_memory: { enabled: 7 } } }", "transport/shared_memory/enabled", ""),
])
def test_a_refused_file_is_named_with_its_key(tmp_path, text, key, reason):
    with pytest.raises(ZenohConfigError) as info:
        config_of(tmp_path, text)
    assert info.value.file == str(tmp_path / "zenoh.json5")
    assert info.value.key == key
    assert reason in str(info.value)
    assert str(info.value).startswith(f"zenoh config {tmp_path / 'zenoh.json5'}: key {key}: ")


def test_unreadable_and_unparsable_files_are_named(tmp_path):
    with pytest.raises(ZenohConfigError, match="cannot read it"):
        ZenohTransport.zenoh_config(TransportConfig(zenoh_config=tmp_path / "missing.json5"))
    with pytest.raises(ZenohConfigError) as info:
        config_of(tmp_path, "{ mode: 'peer',, }")
    assert info.value.key is None and str(tmp_path / "zenoh.json5") in str(info.value)


@pytest.mark.parametrize("command", [["router", "--listen", "tcp/127.0.0.1:0"],
                                     ["sim", "scenarios/scenario1.toml"],
                                     ["agent", "scenarios/scenario1.toml", "--robot", "1"],
                                     ["run", "scenarios/scenario1.toml"],
                                     ["supervise", "scenarios/scenario1.toml"]])
def test_every_process_takes_zenoh_config_and_rejects_a_bad_one(tmp_path, repo_root, command):
    bad = tmp_path / "bad.json5"
    bad.write_text("{ transport: { link: { tx: { lease: 'soon' } } } }")
    done = subprocess.run([sys.executable, "-m", "tlfleet.cli", *command, "--zenoh-config",
                           str(bad)], cwd=repo_root, capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done.stderr
    assert f"zenoh config {bad}: key transport/link/tx/lease: error parsing number" \
        in done.stderr, done.stderr
