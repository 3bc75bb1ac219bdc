"""Argument types shared by several commands: a bad value is an argparse error naming the flag."""

from __future__ import annotations

import argparse
import math
from pathlib import Path


def _number(text: str, ok, bound: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, found {text!r}") from None
    if not (math.isfinite(value) and ok(value)):
        raise argparse.ArgumentTypeError(f"must be a finite number {bound}, found {text}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (a factor or a time), e.g. ``--max-speed 2``."""
    return _number(text, lambda v: v > 0.0, "> 0")


def non_negative_float(text: str) -> float:
    """A finite number ≥ 0 (a time), e.g. ``--backfill-seconds 0``."""
    return _number(text, lambda v: v >= 0.0, "≥ 0")


def positive_int(text: str) -> int:
    """A whole number > 0, e.g. ``--lease-ms 500``."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, found {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, found {text}")
    return value


def fault_spec(text: str):
    """``--fault KIND:TARGET@T[+D]``: parsed at once, so a bad part is a usage
    error naming it, before anything starts."""
    from tlfleet.agent.model.faults import FaultSpecError, parse_fault

    try:
        return parse_fault(text)
    except FaultSpecError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def scenario_file(text: str) -> Path:
    """A scenario TOML file, or the name of a bundled one (``scenario1``: ``tlfleet run scenario1``
    from any directory; :mod:`tlfleet.agent.scenario.bundled`). A bare name that is neither is a
    usage error listing the bundled names; a path is left to the loader, whose error names it."""
    from tlfleet.agent.scenario.bundled import bundled_scenarios, resolve_scenario

    path = resolve_scenario(text)
    if not path.exists() and len(path.parts) == 1 and path.suffix != ".toml":
        names = ", ".join(bundled_scenarios()) or "none installed"
        raise argparse.ArgumentTypeError(f"no file {text!r} and no bundled scenario of that name "
                                         f"(bundled: {names}; `tlfleet init NAME` writes a new "
                                         "one)")
    return path
