"""What the ``needs_system`` tests need, checked once: skip with the reason when it is missing
(``tests/conftest.py`` turns the skip into a failure under TLFLEET_REQUIRE_SYSTEM=1)."""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest


def need_root_netns() -> None:
    if os.geteuid() != 0:
        pytest.skip("needs root for network namespaces (ip netns)")
    for tool, package in (("ip", "iproute2"), ("nft", "nftables")):
        if shutil.which(tool) is None:
            pytest.skip(f"needs `{tool}` (Debian package {package})")


def need_docker() -> None:
    need_root_netns()
    for tool, package in (("docker", "docker.io"), ("dockerd", "docker.io")):
        if shutil.which(tool) is None:
            pytest.skip(f"needs `{tool}` (Debian package {package})")
    if shutil.which("mmdebstrap") is None and shutil.which("debootstrap") is None:
        pytest.skip("needs mmdebstrap or debootstrap for the base image")
    has_compose = subprocess.run(["docker", "compose", "version"], capture_output=True)
    if has_compose.returncode != 0 and shutil.which("docker-compose") is None:
        pytest.skip("needs docker compose (Debian package docker-compose)")
