"""Importing the mjx backend prints nothing: mujoco.mjx's "Failed to import warp" lines (Warp is an
optional second implementation this backend does not use) read as a failure to a user."""

import subprocess
import sys

import pytest

pytest.importorskip("mujoco.mjx")


def test_importing_the_mjx_env_prints_no_warp_failure():
    code = "import econmotor.motor_backend.mjx.env as e; print('mjx', e.mjx.__name__)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "mjx mujoco.mjx\n"
    assert "warp" not in proc.stderr.lower()
