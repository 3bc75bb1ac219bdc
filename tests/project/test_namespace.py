"""One import name, ``tlfleet``: nothing else is installed at top level, nothing in the user's
working directory can shadow a part of it, and the wheel holds only ``tlfleet/``."""

from __future__ import annotations

import glob
import subprocess
import sys
import zipfile
from importlib.metadata import distribution
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TWO_ROBOTS = ROOT / "tests" / "system" / "two_robots.toml"
GENERIC = ("agent", "bus", "cli", "coordinator", "sim")  # the layer folders' own names


def test_the_distribution_declares_tlfleet_alone() -> None:
    assert distribution("tlfleet").read_text("top_level.txt").split() == ["tlfleet"]


def test_the_layer_folders_are_not_importable_at_top_level(tmp_path: Path) -> None:
    """From a neutral directory, the installed project offers ``tlfleet.sim`` but no ``sim``."""
    code = ("import importlib.util, tlfleet.sim, tlfleet.agent, tlfleet.bus\n"
            f"print([n for n in {GENERIC!r} if importlib.util.find_spec(n) is not None])\n")
    done = subprocess.run([sys.executable, "-P", "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


@pytest.mark.slow
def test_the_wheel_holds_only_the_tlfleet_package(tmp_path: Path) -> None:
    """What ``pip show -f tlfleet`` lists after a wheel install: ``tlfleet/…`` and the metadata."""
    done = subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps",
                           "--disable-pip-version-check", "-w", str(tmp_path), str(ROOT)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    (wheel,) = glob.glob(str(tmp_path / "tlfleet-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    tops = {name.split("/")[0] for name in names}
    assert {top for top in tops if not top.endswith(".dist-info")} == {"tlfleet"}
    assert "tlfleet/__init__.py" in names and "tlfleet/cli/__main__.py" in names
    assert "tlfleet/setup.py" not in names
    assert not any(name.startswith(("tlfleet/tests/", "tlfleet/bench/")) for name in names)


@pytest.mark.system
def test_tlfleet_run_ignores_look_alike_modules_in_the_working_directory(tmp_path: Path) -> None:
    """A user's own ``sim.py``, ``agent/`` and ``bus.py`` beside their scenario: the run and every
    process it starts use tlfleet's, and the run ends clean."""
    (tmp_path / "sim.py").write_text("raise SystemExit('the user sim.py was imported')\n")
    (tmp_path / "bus.py").write_text("raise SystemExit('the user bus.py was imported')\n")
    (tmp_path / "agent").mkdir()
    (tmp_path / "agent" / "__init__.py").write_text("raise SystemExit('user agent/ imported')\n")
    (tmp_path / "tlfleet.py").write_text("raise SystemExit('the user tlfleet.py was imported')\n")
    command = Path(sys.executable).with_name("tlfleet")
    done = subprocess.run([str(command), "run", str(TWO_ROBOTS), "--lockstep", "--duration", "3",
                           "--quiet", "--no-report", "--no-rrd", "--out", str(tmp_path / "run")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "outcome: clean" in done.stdout
    logs = "".join(path.read_text() for path in (tmp_path / "run" / "logs").glob("*.log"))
    assert "imported" not in logs
