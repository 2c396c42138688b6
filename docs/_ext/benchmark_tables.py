"""Benchmark results as tables and plots, read from the committed JSON files.

``make bench`` writes ``benchmarks/results/<benchmark>.json`` (see
``benchmarks/_bench.py``): the machine, the date, the versions of the peers and
every table the script printed. Two directives put them in the docs:

``.. benchmark-results:: demosaic``
    The run's machine and versions, then its tables, each under its title.
    ``:match: CPSNR`` keeps only the tables whose title contains one of the
    comma-separated words.

``.. demosaic-speed-quality::``
    A scatter plot of the demosaicers' speed (the speed table's MP/s) against
    their quality (the seven-image CPSNR table's mean), ours and the peers.

A benchmark without a results file gets a note naming the command that makes
one, so the page says what is missing instead of showing old numbers.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, ClassVar

from docutils import nodes
from docutils.parsers.rst import directives
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective


def load(app: Sphinx, name: str) -> dict[str, Any] | None:
    path = Path(app.config.benchmark_results) / f"{name}.json"
    if not path.exists():
        return None
    return json.loads(path.read_text())


def _paragraph(text: str) -> nodes.paragraph:
    return nodes.paragraph(text, text)


def _rich(*parts: str) -> nodes.paragraph:
    """A paragraph of text, with every other part set as code."""
    paragraph = nodes.paragraph()
    for i, part in enumerate(parts):
        paragraph += nodes.literal(part, part) if i % 2 else nodes.Text(part)
    return paragraph


def _missing(name: str) -> list[nodes.Node]:
    note = nodes.note()
    note += _rich(
        f"No results of benchmarks/{name}.py are committed yet: ",
        "make bench",
        " (or ",
        f".venv/bin/python benchmarks/{name}.py",
        ") writes ",
        f"benchmarks/results/{name}.json",
        ", and the next docs build shows its tables here.",
    )
    return [note]


def describe_run(result: dict[str, Any]) -> str:
    """One sentence: which command ran where, when, with which peers."""
    versions = ", ".join(f"{k} {v}" for k, v in sorted(result.get("versions", {}).items()))
    load = result.get("load_average_before")
    load_text = f", load average {load[0]:.1f} at the start" if load else ""
    commit = result.get("commit")
    commit_text = f" at commit {commit}" if commit else ""
    started = result["started"].replace("T", " ").removesuffix("+00:00")
    isa = result.get("instruction_set")
    isa_text = f", kernels built for {isa}" if isa else ""
    return (
        f"{result['command']}{commit_text}, {started} UTC, on "
        f"{result['cpu']} ({result['cores']} cores{load_text}{isa_text}), "
        f"Python {result['python']}; "
        f"versions: {versions}."
    )


def _table(spec: dict[str, Any]) -> list[nodes.Node]:
    """The table under its title (a paragraph: a caption would scroll away
    with a wide table)."""
    headers, rows = spec["headers"], spec["rows"]
    out: list[nodes.Node] = []
    if spec.get("title"):
        title = nodes.paragraph(classes=["benchmark-title"])
        title += nodes.strong(spec["title"], spec["title"])
        out.append(title)
    table = nodes.table(classes=["benchmark-table"])
    out.append(table)
    group = nodes.tgroup(cols=len(headers))
    table += group
    for _ in headers:
        group += nodes.colspec(colwidth=1)
    head = nodes.thead()
    group += head
    body = nodes.tbody()
    group += body
    for cells, parent in [(headers, head), *((r, body) for r in rows)]:
        row = nodes.row()
        for cell in cells:
            entry = nodes.entry()
            entry += _paragraph(str(cell))
            row += entry
        parent += row
    return out


class BenchmarkResults(SphinxDirective):
    required_arguments = 1
    option_spec: ClassVar = {"match": directives.unchanged}

    def run(self) -> list[nodes.Node]:
        name = self.arguments[0]
        path = Path(self.config.benchmark_results) / f"{name}.json"
        self.env.note_dependency(str(path))
        result = load(self.env.app, name)
        if result is None:
            return _missing(name)
        words = [w.strip() for w in self.options.get("match", "").split(",") if w.strip()]
        out: list[nodes.Node] = []
        run = nodes.paragraph()
        run += nodes.strong("Run: ", "Run: ")
        run += nodes.literal(result["command"], result["command"])
        run += nodes.Text(describe_run(result).removeprefix(result["command"]))
        out.append(run)
        for note in result.get("opening_notes", []):
            out.append(_paragraph(note))
        for spec in result["tables"]:
            if words and not any(w in spec["title"] for w in words):
                continue
            out.extend(_table(spec))
            for note in spec.get("notes", []):
                out.append(_paragraph(note))
        for note in result.get("closing_notes", []):
            out.append(_paragraph(note))
        return out


def _number(text: str) -> float | None:
    match = re.search(r"-?\d+(\.\d+)?", text)
    return float(match.group()) if match else None


# Names of other methods: plotted, they would sit on (or beside) their method.
ALIASES = {"ours best", "ours quality"}


# The quality a method is plotted at: the mean over the validation subsets
# when the run has them (the seven scikit-image images alone once picked the
# wrong winner), else the mean over the seven.
QUALITY_COLUMNS = (
    ("mean of subsets", "mean CPSNR of the validation subsets"),
    ("mean", "mean CPSNR over the seven scikit-image images"),
)


def _table_with(result: dict[str, Any], prefix: str, header: str) -> dict[str, Any] | None:
    return next(
        (t for t in result["tables"] if t["title"].startswith(prefix) and header in t["headers"]),
        None,
    )


def quality_column(result: dict[str, Any]) -> tuple[dict[str, Any], str, str] | None:
    """The CPSNR table to plot, its column and what that column means."""
    for column, meaning in QUALITY_COLUMNS:
        table = _table_with(result, "CPSNR", column)
        if table is not None:
            return table, column, meaning
    return None


def speed_and_quality(result: dict[str, Any]) -> list[tuple[str, float, float]]:
    """(method, MP/s, CPSNR dB) for each method in both the speed table and
    the CPSNR table of a demosaic run (see ``QUALITY_COLUMNS``)."""
    speed = _table_with(result, "Speed:", "MP/s")
    found = quality_column(result)
    if speed is None or found is None:
        return []
    quality, column, _ = found
    rate_at = speed["headers"].index("MP/s")
    rates = {row[0]: _number(row[rate_at]) for row in speed["rows"]}
    mean_at = quality["headers"].index(column)
    points = []
    for row in quality["rows"]:
        name, mean = row[0], _number(row[mean_at])
        if name in ALIASES:
            continue
        # The quality table names LibRaw's and OpenCV's methods as the speed
        # table does; colour-demosaicing's rows are "colour <method>" in both.
        rate = rates.get(name)
        if rate is not None and mean is not None:
            points.append((name, rate, mean))
    return points


class DemosaicSpeedQuality(SphinxDirective):
    def run(self) -> list[nodes.Node]:
        path = Path(self.config.benchmark_results) / "demosaic.json"
        self.env.note_dependency(str(path))
        result = load(self.env.app, "demosaic")
        if result is None:
            return _missing("demosaic")
        points = speed_and_quality(result)
        if not points:
            note = nodes.note()
            note += _rich(
                "The committed ",
                "benchmarks/results/demosaic.json",
                " lacks the speed or the quality section (it was made with sections named on "
                "the command line); a full ",
                "make bench",
                " run has both, and the plot of one against the other appears here.",
            )
            return [note]
        meaning = quality_column(result)[2]
        image = self._plot(points, meaning)
        figure = nodes.figure()
        figure += nodes.image(uri=image)
        caption = (
            f"Speed (24 MP uint16 mosaic, best of N) against quality ({meaning}) of every "
            "demosaicer in one run of benchmarks/demosaic.py; up and to the right is better."
        )
        figure += nodes.caption(caption, caption)
        return [figure]

    def _plot(self, points: list[tuple[str, float, float]], meaning: str) -> str:
        import matplotlib.pyplot as plt

        out = Path(self.env.srcdir) / "_generated"
        out.mkdir(exist_ok=True)
        fig, ax = plt.subplots(figsize=(8, 5.5), layout="constrained")
        for name, rate, db in points:
            ours = name.startswith("ours ")
            ax.scatter(rate, db, s=40, color="C0" if ours else "C1", marker="o" if ours else "s")
            label = name.removeprefix("ours ")
            ax.annotate(label, (rate, db), textcoords="offset points", xytext=(5, 3), fontsize=8)
        ax.set_xscale("log")
        ax.set_xlabel("speed, MP/s (log scale)")
        ax.set_ylabel(f"dB, {meaning}")
        ax.scatter([], [], color="C0", marker="o", label="imgform-rs")
        ax.scatter([], [], color="C1", marker="s", label="peers")
        ax.legend(loc="lower left")
        ax.grid(True, which="both", alpha=0.3)
        fig.savefig(out / "demosaic_speed_quality.png", dpi=110)
        plt.close(fig)
        return "/_generated/demosaic_speed_quality.png"


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_config_value("benchmark_results", "", "env")
    app.add_directive("benchmark-results", BenchmarkResults)
    app.add_directive("demosaic-speed-quality", DemosaicSpeedQuality)
    return {"parallel_read_safe": True, "version": "1"}
