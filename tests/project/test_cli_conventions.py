"""Every public ``tlfleet`` sub-command follows the CLI's conventions (tlfleet.cli.conventions):
its ``--help`` has examples that parse and every exit code it can return; internal commands stay
out of ``tlfleet --help``; ``-v``/``-q`` work before and after the sub-command; ``-o`` is
``--out``; shell completion scripts are generated from the full parser."""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import re
import shlex

import pytest
from tlfleet.cli import conventions
from tlfleet.cli.main import COMMANDS, INTERNAL, build_parser, command_module, full_parser, main

PUBLIC = sorted(set(COMMANDS) - INTERNAL)


def _help(argv: list[str]) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 0
    return out.getvalue()


@pytest.mark.parametrize("name", PUBLIC)
def test_help_has_examples_and_exit_codes(name: str) -> None:
    text = _help([name, "--help"])
    assert "\nexamples:\n" in text and "\nexit codes:\n" in text, text
    examples = text.split("\nexamples:\n", 1)[1].split("\nexit codes:\n", 1)[0]
    assert f"  tlfleet {name}" in examples
    codes = [int(c) for c in re.findall(r"^\s+(\d+)  ", text.split("\nexit codes:\n", 1)[1],
                                        re.M)]
    assert 0 in codes and 2 in codes and 130 in codes, codes
    assert codes == sorted(codes)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_example_parses(name: str) -> None:
    """An example in the help is a command line the parser accepts (no stale flag)."""
    parser = full_parser()
    module = command_module(name)
    assert module.EXAMPLES, f"{name}: no example"
    for line, says in module.EXAMPLES:
        assert says.strip()
        words = shlex.split(line.split(" > ")[0])
        assert words[:2] == ["tlfleet", name], line
        args = parser.parse_args(words[1:])
        assert args.command == name


def test_internal_commands_are_hidden_but_work() -> None:
    listing = _help(["--help"])
    for name in PUBLIC:
        assert re.search(rf"^\s+{re.escape(name)}\s", listing, re.M), name
    for name in INTERNAL:
        assert not re.search(rf"^\s+{re.escape(name)}\s", listing, re.M), name
        assert "examples:" in _help([name, "--help"])


@pytest.mark.parametrize("argv, verbose, quiet", [
    (["-v", "check", "x.toml"], 1, 0),
    (["check", "x.toml", "-v"], 1, 0),
    (["-v", "check", "-vv", "x.toml"], 3, 0),
    (["check", "x.toml", "-q"], 0, 1),
    (["-q", "check", "--quiet", "x.toml"], 0, 2),
])
def test_verbosity_anywhere(argv: list[str], verbose: int, quiet: int) -> None:
    parser, subparsers = build_parser()
    conventions.add_verbosity_arguments(subparsers["check"], after_command=True)
    subparsers["check"].add_argument("scenario", nargs="+")
    args = parser.parse_args(argv)
    conventions.merge_verbosity(args)
    assert (args.verbose, args.quiet) == (verbose, quiet)


@pytest.mark.parametrize("verbose, quiet, default, level", [
    (0, 0, logging.WARNING, logging.WARNING), (1, 0, logging.WARNING, logging.INFO),
    (2, 0, logging.WARNING, logging.DEBUG), (5, 0, logging.WARNING, logging.DEBUG),
    (0, 1, logging.WARNING, logging.ERROR), (0, 3, logging.WARNING, logging.ERROR),
    (0, 0, logging.INFO, logging.INFO), (0, 1, logging.INFO, logging.WARNING),
])
def test_log_level(verbose: int, quiet: int, default: int, level: int) -> None:
    args = argparse.Namespace(verbose=verbose, quiet=quiet)
    assert conventions.log_level(args, default) == level


def test_short_out_is_out() -> None:
    parser = full_parser()
    for argv in (["run", "s.toml", "-o", "d"], ["supervise", "s.toml", "-o", "d"],
                 ["keys", "s.toml", "-o", "d"], ["compose", "s.toml", "-o", "d"],
                 ["replay", "r", "-o", "d"]):
        assert str(parser.parse_args(argv).out) == "d", argv


@pytest.mark.parametrize("name", ["check", "run", "translate", "plan", "monitor", "report",
                                  "supervise"])
def test_result_commands_take_json(name: str) -> None:
    assert "--json" in _help([name, "--help"])


@pytest.mark.parametrize("shell", ["bash", "zsh"])
def test_completion_script(shell: str) -> None:
    pytest.importorskip("shtab")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["completion", shell]) == 0
    script = out.getvalue()
    for name in PUBLIC:
        assert name in script, name
    assert "--lockstep" in script and "--robot" in script  # flags of the sub-commands too
    if shell == "bash":  # the commands offered after `tlfleet `: the public ones, exactly
        offered = re.search(r"^_shtab_tlfleet_subparsers=\((.*)\)$", script, re.M)
        assert offered is not None and sorted(offered.group(1).split()) == PUBLIC


def test_epilog_layout() -> None:
    text = conventions.epilog([("tlfleet x a", "does a")], {0: "ok", 7: "seven"})
    assert text.splitlines() == ["examples:", "  tlfleet x a", "      does a", "",
                                 "exit codes:", "    0  ok", "    2  " +
                                 conventions.COMMON_EXIT_CODES[2], "    7  seven",
                                 "  130  " + conventions.COMMON_EXIT_CODES[130]]


def _stdout_of(argv: list[str]) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(argv) == 0
    return out.getvalue()


def test_check_json_is_the_scenario(scenario_paths) -> None:
    import json

    from tlfleet.agent.scenario import load_scenario

    lines = _stdout_of(["check", "--json", *map(str, scenario_paths)]).splitlines()
    assert len(lines) == len(scenario_paths)
    for line, path in zip(lines, scenario_paths, strict=True):
        data, scenario = json.loads(line), load_scenario(path)
        assert data["name"] == scenario.name and data["duration"] == scenario.duration
        assert [r["id"] for r in data["robots"]] == sorted(r.id for r in scenario.robots)
        assert {r["name"] for r in data["regions"]} == {r.name for r in scenario.regions}


def test_translate_json_is_the_automaton() -> None:
    import json

    from tlfleet.agent.ltl.buchi import translate

    formula = "G F a & G (b -> F c)"
    data = json.loads(_stdout_of(["translate", formula, "--json"]))
    buchi = translate(formula)
    assert data["states"] == buchi.num_states and len(data["edges"]) == buchi.num_edges
    assert data["accepting"] == sorted(buchi.accepting)
    assert data["initial"] == list(buchi.initial)
    # every edge's guard text is the automaton's own guard, in edge order
    assert [e[2] for e in data["edges"]] == [buchi.guard_text(g) for out in buchi.edges
                                             for _, g in out]


@pytest.fixture
def scenario_paths():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2] / "scenarios"
    return sorted(root.glob("scenario[123].toml"))
