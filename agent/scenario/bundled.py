"""The example scenarios that come with the package: the paper's Scenarios 1-3, found by name.

They are the repository's ``scenarios/*.toml``, installed as package data under
``tlfleet/scenarios/`` (setup.py), so ``tlfleet run scenario1`` works from any directory after
``pip install tlfleet``, and a checkout finds the same files in place.
"""

from __future__ import annotations

from pathlib import Path

#: where the bundled scenarios are: ``scenarios/`` beside the package's ``__init__.py`` (the
#: repository's root in a checkout, ``site-packages/tlfleet`` in an install)
BUNDLED_DIR = Path(__file__).resolve().parents[2] / "scenarios"


def bundled_scenarios() -> dict[str, Path]:
    """``{name: path}`` of every bundled scenario (``scenario1`` → ``…/scenarios/scenario1.toml``),
    sorted by name."""
    if not BUNDLED_DIR.is_dir():
        return {}
    return {path.stem: path for path in sorted(BUNDLED_DIR.glob("*.toml"))}


def resolve_scenario(text: str) -> Path:
    """The file a command-line scenario argument names: ``text`` itself when such a file exists
    (a file always wins), else the bundled scenario of that name (``scenario1`` or
    ``scenario1.toml``, no directory part), else ``text`` unchanged, for the loader to report as
    missing."""
    given = Path(text)
    if given.exists() or len(given.parts) != 1:
        return given
    bundled = bundled_scenarios()
    return bundled.get(given.stem if given.suffix == ".toml" else text, given)
