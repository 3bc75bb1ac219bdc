"""A bad ``$TLFLEET_CODEC`` is a one-line error of the command, not a traceback (it is read when
``tlfleet.bus.protocol.fast_paths`` is imported, so only a fresh process shows it)."""

from __future__ import annotations

import os
import subprocess
import sys


def test_a_bad_codec_setting_is_a_clear_error(repo_root):
    env = {**os.environ, "TLFLEET_CODEC": "fastest"}
    done = subprocess.run([sys.executable, "-m", "tlfleet.cli", "run", "--help"],
                          cwd=repo_root, env=env, capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    assert done.stderr.strip() == ("tlfleet run: $TLFLEET_CODEC = 'fastest': expected one of "
                                   "auto, native, python")
