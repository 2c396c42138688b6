"""Shared test helpers."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable

import pytest


@pytest.fixture
def run_with_threads() -> Callable[[str, int], bytes]:
    """Runs a Python snippet in a fresh interpreter with ``RAYON_NUM_THREADS``
    set (rayon reads it once, at pool start) and returns its stdout; tests
    compare the bytes of 1 and N threads."""

    def run(code: str, threads: int) -> bytes:
        env = {**os.environ, "RAYON_NUM_THREADS": str(threads)}
        done = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, check=True, timeout=300
        )
        return done.stdout

    return run
