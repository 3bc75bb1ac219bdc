"""The scenario reference (tlfleet.agent.scenario.reference): every key the loader accepts is
documented in docs/scenario.md with its type, unit, default and meaning; the JSON Schema
``tlfleet schema`` prints accepts the shipped scenarios and rejects the broken corpus's type
errors (checked by an independent validator, ``jsonschema``)."""

from __future__ import annotations

import dataclasses
import json
import re
import tomllib
from pathlib import Path

import pytest
from broken_corpus import CASES
from tlfleet.agent.model import scenario as model
from tlfleet.agent.scenario import validation
from tlfleet.agent.scenario.reference import REQUIRED, json_schema, keys, markdown
from tlfleet.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "scenario.md"
SHIPPED = sorted([*(ROOT / "scenarios").glob("*.toml"), *(ROOT / "tests" / "scenario" /
                                                           "corpus").glob("*.toml")])
# the broken corpus's cases a schema can see: wrong types, values outside an enum, unknown or
# missing keys
TYPE_ERRORS = ("duration string", "pose wrong length", "robot id string", "kind unknown",
               "misspelt required key", "misspelt robot key", "misspelt section",
               "misspelt optional key", "misspelt array of tables", "unknown key",
               "duration negative", "no robots", "empty file", "stl written after "
               "[robots.limits]", "top-level key written after [sim]",
               "top-level key written after [[robots]]")


def test_every_key_the_loader_reads_is_documented():
    documented = {k.name for k in keys()}
    assert documented | {"arena", "ltl", "stl", "sim", "regions",
                                                   "robots", "obstacles", "navigation",
                                                   "faults", "limits"} >= validation.KNOWN_KEYS
    for cls in (model.LtlParams, model.StlParams, model.SimParams, model.NavParams,
                model.UnicycleLimits, model.OmniLimits):
        for f in dataclasses.fields(cls):
            key = next(k for k in keys() if k.name == f.name and
                       (k.table.startswith("robots") or k.default == f.default))
            assert key.meaning and key.meaning != "–", (cls.__name__, f.name)
            assert key.default == f.default or key.default == REQUIRED


def test_docs_scenario_md_is_the_generated_reference():
    text = DOC.read_text(encoding="utf-8")
    assert text == markdown(), ("docs/scenario.md is stale: python -m "
                                "tlfleet.agent.scenario.reference > docs/scenario.md")
    for key in keys():  # each key a row: name, type, unit, default, meaning, example
        row = next((line for line in text.splitlines() if line.startswith(f"| `{key.name}` |")
                    and key.meaning.replace("|", "\\|") in line), None)
        assert row is not None, key.path
        assert row.count("|") >= 7


def test_the_schema_accepts_the_shipped_scenarios():
    jsonschema = pytest.importorskip("jsonschema")
    schema = json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    assert SHIPPED
    for path in SHIPPED:
        errors = [e.message for e in validator.iter_errors(tomllib.loads(path.read_text()))]
        assert errors == [], path


@pytest.mark.parametrize("name", TYPE_ERRORS)
def test_the_schema_rejects_the_broken_corpus_type_errors(name, tmp_path):
    jsonschema = pytest.importorskip("jsonschema")
    case = next(c for c in CASES if c.name == name)
    data = tomllib.loads(case.make(tmp_path).read_text())
    errors = list(jsonschema.Draft202012Validator(json_schema()).iter_errors(data))
    assert errors, name


def test_schema_command_prints_and_writes_it(tmp_path, capsys):
    assert main(["schema"]) == 0
    assert json.loads(capsys.readouterr().out) == json_schema()
    out = tmp_path / "s.json"
    assert main(["schema", "--out", str(out)]) == 0
    assert json.loads(out.read_text()) == json_schema()
    # the types and enums come from the model: a new [sim] field is in the schema at once
    sim = json_schema()["properties"]["sim"]["properties"]
    assert set(sim) == {f.name for f in dataclasses.fields(model.SimParams)}
    assert re.search(r"\[Hz\]", sim["mocap_rate"]["description"])
