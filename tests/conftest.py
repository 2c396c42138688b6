"""Shared test settings and helpers.

Hypothesis profiles follow polars: "ci" (the default) keeps `make test` short,
"expensive" explores far more; choose with HYPOTHESIS_PROFILE=expensive.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci",
    max_examples=60,
    deadline=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("expensive", max_examples=2000, deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


def output_with_threads(code: str, threads: int) -> bytes:
    """Runs ``code`` in a fresh interpreter with RAYON_NUM_THREADS=threads and
    returns what it wrote to stdout (write the result bytes with
    ``sys.stdout.buffer.write``). Rayon reads the variable once per process, so
    thread-count independence can only be tested across processes."""
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        env=env,
        capture_output=True,
        check=True,
        timeout=300,
    )
    return done.stdout


def shared_path(rel: str) -> Path | None:
    """``../shared/<rel>`` beside the checkout (or beside a folder of
    worktrees above it), or None when it is absent."""
    root = Path(__file__).resolve().parents[1]
    for base in (root, *root.parents):
        p = base.parent / "shared" / rel
        if p.exists():
            return p
    return None


def assert_clash_refused(captured, command: str, inputs: list, out: Path) -> None:
    """``imgform command`` refused two ``inputs`` that would write one output
    in ``out`` in one line, and wrote nothing."""
    first, second = inputs
    assert captured.out == ""
    assert captured.err == (
        f"imgform {command}: inputs would overwrite each other's output: {first} and {second} "
        f"-> {out / (Path(first).stem + '.png')}; nothing was written (rename them, or run "
        "them into different folders)\n"
    )
    assert not out.exists()
