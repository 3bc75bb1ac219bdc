"""What a user installs: ``make dist``'s sdist and wheel, the wheel installed into a fresh virtual
environment outside the repository, ``tlfleet run scenario1`` there (the bundled scenario, found
by name) ending clean, and the files ``pip show -f tlfleet`` lists all under ``tlfleet/``.

The fresh environment installs the dependencies from the package index (pip's cache makes a
second run quick); the test is ``slow``: ``make test`` runs it, ``make test-fast`` does not."""

from __future__ import annotations

import email
import json
import os
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _run(argv: list[str], cwd: Path, timeout: float) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope="module")
def dist(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    done = _run(["make", "dist", f"DIST={out}", f"PYTHON={sys.executable}"], ROOT, 900)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return out


@pytest.mark.slow
def test_the_wheel_is_manylinux_abi3_with_the_metadata(dist: Path) -> None:
    (wheel,) = dist.glob("tlfleet-*.whl")
    (sdist,) = dist.glob("tlfleet-*.tar.gz")
    # one wheel for every CPython >= 3.11 (stable ABI), a platform tag PyPI accepts
    python_tag, abi_tag, platform_tag = wheel.stem.split("-")[2:5]
    assert (python_tag, abi_tag) == ("cp311", "abi3")
    assert platform_tag.startswith("manylinux_"), platform_tag
    names = zipfile.ZipFile(wheel).namelist()
    assert {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")} \
        == {"tlfleet"}
    for module in ("tlfleet/bus/protocol/_wire", "tlfleet/sim/_tracking",
                   "tlfleet/agent/nav/_dwa"):
        assert f"{module}.abi3.so" in names, module
    for name in ("scenario1", "scenario2", "scenario3"):
        assert f"tlfleet/scenarios/{name}.toml" in names
    info = next(n for n in names if n.endswith(".dist-info/METADATA"))
    meta = email.message_from_string(zipfile.ZipFile(wheel).read(info).decode())
    assert meta["License-Expression"] == "Apache-2.0"
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert len(meta.get_all("Classifier")) >= 5 and meta["Keywords"]
    assert meta["Author"] or meta["Author-email"]
    description = meta.get_payload()
    assert "tlfleet run scenario1" in description
    assert "](" not in description or "](http" in description  # no repository-relative link
    assert f"{sdist.name[:-len('.tar.gz')]}/LICENSE" in \
        subprocess.run(["tar", "tzf", str(sdist)], capture_output=True, text=True).stdout


@pytest.mark.slow
def test_the_wheel_runs_scenario1_outside_the_repository(dist: Path, tmp_path: Path) -> None:
    (wheel,) = dist.glob("tlfleet-*.whl")
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    bin_dir = env_dir / "bin"
    work = tmp_path / "work"
    work.mkdir()
    done = _run([str(bin_dir / "python"), "-m", "pip", "install", "--quiet",
                 "--disable-pip-version-check", str(wheel)], work, 900)
    assert done.returncode == 0, done.stderr[-3000:]
    where = _run([str(bin_dir / "python"), "-c", "import tlfleet; print(tlfleet.__file__)"],
                 work, 60)
    assert Path(where.stdout.strip()).is_relative_to(env_dir), where.stdout  # not the checkout

    shown = _run([str(bin_dir / "python"), "-m", "pip", "show", "-f", "tlfleet"], work, 60)
    files = shown.stdout.split("Files:", 1)[1].split()
    assert {f.split("/")[0] for f in files if not f.split("/")[0].endswith(".dist-info")
            and not f.startswith("../")} == {"tlfleet"}

    done = _run([str(bin_dir / "tlfleet"), "run", "scenario1", "-o", str(work / "run"),
                 "--no-rrd", "--no-figures", "--json", "-q"], work, 600)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    result = json.loads(done.stdout)
    assert result["verdict"]["label"] == "clean"
    assert result["end"]["t_end"] == pytest.approx(90.0, abs=0.02)
    assert Path(result["run_dir"]) == work / "run"
    assert (work / "run" / "trajectory.csv").is_file()
    # the scenario the run recorded is the bundled one, byte for byte
    assert (work / "run" / "scenario.toml").read_bytes() == \
        (ROOT / "scenarios" / "scenario1.toml").read_bytes()
