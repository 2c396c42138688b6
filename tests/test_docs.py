"""The documentation, checked without a full Sphinx build or a browser.

``make docs`` builds the site with warnings as errors; these checks keep
``make test`` honest about the parts that break silently between two builds:
a public name without an API page, an API entry whose object was renamed, a
gallery example that no longer runs or draws fewer figures than the guide
shows, and a benchmark record the docs cannot read.
"""

from __future__ import annotations

import importlib
import inspect
import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import imgform_rs
from imgform_rs import (
    batch,
    colorspace,
    dispersion,
    dng,
    film,
    lens,
    scene,
    spectral,
    three_colour,
)

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
EXAMPLES = sorted((DOCS / "examples").glob("plot_*.py"))


def _defined_here(module) -> list[str]:
    """A module without ``__all__``: its public functions and classes."""
    return [
        name
        for name, obj in vars(module).items()
        if not name.startswith("_")
        and (inspect.isfunction(obj) or inspect.isclass(obj))
        and obj.__module__ == module.__name__
    ]


PUBLIC = {
    "imgform_rs": list(imgform_rs.__all__),
    "imgform_rs.batch": list(batch.__all__),
    "imgform_rs.colorspace": list(colorspace.__all__),
    "imgform_rs.dispersion": _defined_here(dispersion),
    "imgform_rs.dng": _defined_here(dng),
    "imgform_rs.film": _defined_here(film),
    "imgform_rs.lens": list(lens.__all__),
    "imgform_rs.scene": _defined_here(scene),
    "imgform_rs.spectral": _defined_here(spectral),
    "imgform_rs.three_colour": _defined_here(three_colour),
}


def api_entries() -> list[str]:
    """The fully qualified names listed in docs/api.rst's autosummary tables,
    in the module of the ``currentmodule`` (or ``module``) above each."""
    module, entries, in_table = "", [], False
    for line in (DOCS / "api.rst").read_text().splitlines():
        if line.startswith((".. currentmodule::", ".. module::")):
            module = line.split("::", 1)[1].strip()
            in_table = False
        elif line.startswith(".. autosummary::"):
            in_table = True
        elif in_table and line.startswith("   ") and not line.strip().startswith(":"):
            entries.append(f"{module}.{line.strip()}")
        elif in_table and line.strip() and not line.startswith("   "):
            in_table = False
    return entries


def _resolve(fullname: str):
    module, _, name = fullname.rpartition(".")
    return getattr(importlib.import_module(module), name)


def test_public_modules_are_the_ones_checked():
    """A public submodule with an ``__all__`` of its own (not re-exported by
    ``imgform_rs``) must join PUBLIC, and so the API reference."""
    unchecked = []
    for path in (ROOT / "python" / "imgform_rs").glob("*.py"):
        name = f"imgform_rs.{path.stem}"
        if path.stem.startswith("_") or name in PUBLIC or "__all__" not in path.read_text():
            continue
        own = set(getattr(importlib.import_module(name), "__all__", ())) - set(imgform_rs.__all__)
        if own:
            unchecked.append(f"{name}: {sorted(own)}")
    assert not unchecked, f"public names missing from PUBLIC and docs/api.rst: {unchecked}"


@pytest.mark.parametrize("module", sorted(PUBLIC))
def test_every_public_name_has_an_api_entry(module):
    entries = api_entries()
    missing = []
    for name in PUBLIC[module]:
        obj = getattr(importlib.import_module(module), name)
        # Constants are documented in the module that defines them (where their
        # docstrings are), e.g. imgform_rs.demosaic.DEMOSAIC_METHODS.
        if not any(e.rpartition(".")[2] == name and _resolve(e) is obj for e in entries):
            missing.append(name)
    assert not missing, f"not in docs/api.rst: {missing}"


def test_every_api_entry_is_public_and_listed_once():
    entries = api_entries()
    assert len(entries) == len(set(entries))
    public = {(m, n) for m, names in PUBLIC.items() for n in names}
    for entry in entries:
        _resolve(entry)  # raises if the name went away
        name = entry.rpartition(".")[2]
        assert any(n == name for _, n in public), f"{entry} is not a public name"


def test_every_module_the_pages_name_has_a_target():
    """A :mod: reference to a module the site does not declare renders as
    plain code, linking nowhere, and the -W build does not say so.
    (``imgform_rs.demosaic`` and ``develop`` cannot be declared: their names
    are the functions'.)"""
    declared = set(re.findall(r"^\.\. module:: (\S+)$", (DOCS / "api.rst").read_text(), re.M))
    pages = [DOCS / "api.rst", DOCS / "index.rst", DOCS / "install.rst"]
    pages += sorted((DOCS / "guide").glob("*.rst"))
    named = {m for page in pages for m in re.findall(r":mod:`~?([\w.]+)`", page.read_text())}
    assert named and not named - declared, f"no .. module:: for {sorted(named - declared)}"


def test_autosummary_writes_a_page_per_entry(tmp_path):
    """What ``make docs`` runs first: one generated page per API entry."""
    pytest.importorskip("sphinx")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "sphinx.ext.autosummary.generate",
            "-o",
            str(tmp_path),
            "-t",
            str(DOCS / "_templates"),
            str(DOCS / "api.rst"),
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    pages = {p.stem for p in tmp_path.glob("*.rst")}
    assert pages == set(api_entries())
    camera = (tmp_path / "imgform_rs.Camera.rst").read_text()
    assert ".. autoclass:: Camera" in camera and ":members:" in camera


# Runs an example as sphinx-gallery does (in its folder, plt.show() drawing
# nothing) and prints how many figures it made.
RUNNER = textwrap.dedent(
    """
    import runpy, sys
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plt.show = lambda *args, **kwargs: None
    runpy.run_path(sys.argv[1], run_name="__main__")
    print("figures:", len(plt.get_fignums()))
    """
)


def _figures_shown_in_docs(example: str) -> set[int]:
    """The figure numbers of ``example`` that the rst pages show."""
    pattern = re.compile(rf"sphx_glr_{re.escape(example)}_(\d{{3}})\.png")
    numbers = set()
    for page in DOCS.rglob("*.rst"):
        if "_build" in page.parts or "generated" in page.parts:
            continue
        numbers |= {int(n) for n in pattern.findall(page.read_text())}
    return numbers


def test_there_are_gallery_examples():
    assert len(EXAMPLES) >= 9


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.stem)
def test_gallery_example_runs(script):
    # The package under test, wherever it was imported from (an installed
    # build, or the checkout's python/ folder on PYTHONPATH).
    package_root = str(Path(imgform_rs.__file__).resolve().parents[1])
    path = os.pathsep.join([package_root, *filter(None, [os.environ.get("PYTHONPATH")])])
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=path)
    done = subprocess.run(
        [sys.executable, "-c", RUNNER, str(script)],
        cwd=script.parent,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    figures = int(done.stdout.rsplit("figures:", 1)[1])
    assert figures >= 1, f"{script.name} draws nothing"
    shown = _figures_shown_in_docs(script.stem)
    assert all(n <= figures for n in shown), f"the docs show figure(s) {shown}, it draws {figures}"


def test_guide_figures_name_existing_examples():
    names = {p.stem for p in EXAMPLES}
    for page in (DOCS / "guide").glob("*.rst"):
        for example in re.findall(r"sphx_glr_(plot_\w+?)_\d{3}\.png", page.read_text()):
            assert example in names, f"{page.name} shows a figure of {example}, which is gone"


def _write_probe(folder: Path) -> Path:
    """A benchmark of two tables beside a copy of _bench.py."""
    (folder / "_bench.py").write_text((ROOT / "benchmarks" / "_bench.py").read_text())
    script = folder / "probe.py"
    script.write_text(
        textwrap.dedent(
            """
            from _bench import table
            print("## Speed: a title")
            print("and its second line\\n")
            print(table(["method", "MP/s"], [["ours mlri", "100"], ["LibRaw AHD", "30"]]))
            print("\\nA note between the tables\\n")
            print("## CPSNR (dB) on the seven")
            rows = [["ours mlri", "40.1", "40.0"], ["ours best", "40.1", "40.0"]]
            print(table(["method", "a", "mean"], rows))
            print("closing line")
            """
        )
    )
    return script


def test_benchmark_tables_are_recorded(tmp_path):
    script = _write_probe(tmp_path)
    env = dict(os.environ, IMGFORM_BENCH_RESULTS=str(tmp_path / "results"))
    done = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "| ours mlri  | 100  |" in done.stdout  # still printed as before
    record = json.loads((tmp_path / "results" / "probe.json").read_text())
    for key in ("cpu", "cores", "started", "versions", "commit", "load_average_before"):
        assert key in record
    assert "numpy" in record["versions"]
    speed, quality = record["tables"]
    assert speed["title"] == "Speed: a title and its second line"
    assert speed["rows"] == [["ours mlri", "100"], ["LibRaw AHD", "30"]]
    # A paragraph before a heading closes the table above it.
    assert speed["notes"] == ["A note between the tables"]
    assert quality["notes"] == []
    assert record["opening_notes"] == []
    assert record["closing_notes"] == ["closing line"]


def test_a_record_from_uncommitted_code_says_so(tmp_path):
    script = _write_probe(tmp_path)
    env = dict(os.environ, IMGFORM_BENCH_RESULTS=str(tmp_path / "results"))

    def git(*args):
        subprocess.run(
            ["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
            cwd=tmp_path,
            check=True,
            capture_output=True,
        )

    def recorded_commit():
        subprocess.run(
            [sys.executable, str(script)], cwd=tmp_path, env=env, check=True, capture_output=True
        )
        return json.loads((tmp_path / "results" / "probe.json").read_text())["commit"]

    git("init", "-q")
    git("add", "_bench.py", "probe.py")
    git("commit", "-q", "-m", "probe")
    clean = recorded_commit()
    assert re.fullmatch(r"[0-9a-f]{7,}", clean)
    (tmp_path / "_bench.py").write_text((tmp_path / "_bench.py").read_text() + "# edited\n")
    assert recorded_commit() == f"{clean}-dirty"


def test_a_failed_benchmark_keeps_the_last_record(tmp_path):
    script = _write_probe(tmp_path)
    script.write_text(script.read_text() + "raise RuntimeError('interrupted')\n")
    env = dict(os.environ, IMGFORM_BENCH_RESULTS=str(tmp_path / "results"))
    done = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True)
    assert done.returncode != 0
    assert not (tmp_path / "results" / "probe.json").exists()


def test_the_docs_read_benchmark_records(tmp_path):
    """The committed records, and a probe's, through the docs extension."""
    pytest.importorskip("docutils")
    pytest.importorskip("sphinx")
    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        benchmark_tables = importlib.import_module("benchmark_tables")
    finally:
        sys.path.remove(str(DOCS / "_ext"))
    script = _write_probe(tmp_path)
    env = dict(os.environ, IMGFORM_BENCH_RESULTS=str(tmp_path))
    subprocess.run([sys.executable, str(script)], env=env, check=True, capture_output=True)
    probe = json.loads((tmp_path / "probe.json").read_text())
    # "best" is an alias of mlri: one point per method.
    assert benchmark_tables.speed_and_quality(probe) == [("ours mlri", 100.0, 40.0)]
    assert "python benchmarks/probe.py" in benchmark_tables.describe_run(probe)
    for path in (ROOT / "benchmarks" / "results").glob("*.json"):
        record = json.loads(path.read_text())
        assert record["benchmark"] == path.stem
        assert record["tables"], f"{path.name} holds no table"
        benchmark_tables.describe_run(record)


def test_the_readme_summary_follows_the_records():
    """README.md's benchmark table is the one benchmarks/summary.py makes from
    the committed records: a re-run benchmark (or a renamed row) without
    ``summary.py --write`` fails here instead of leaving stale numbers."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        summary = importlib.import_module("summary")
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    readme = (ROOT / "README.md").read_text()
    assert summary.readme_with(summary.summary(), readme) == readme
