"""Scale-out on Dask: many raws or plates on a cluster, one huge mosaic in chunks.

Needs the optional extra (``pip install imgform-rs[dask]``); the rest of the
package never imports Dask, and this module imports it only when called.

:func:`develop_many` and :func:`align_many` run one task per file on a
``distributed.Client`` (a local cluster of worker processes when none is
given). The promises that make a large batch safe to run and to re-run:

- **atomic outputs**: each file is written under a temporary name in the
  output folder and renamed into place (``os.replace``), so a crash or a
  killed worker never leaves a half-written file under its final name;
- **resumable**: a file whose output exists is skipped (``overwrite=False``),
  so re-running an interrupted batch only does what is left. An interrupt
  (``KeyboardInterrupt``) drops the files no worker has started, waits for
  those in progress (a task cannot be stopped) and writes the report with
  every file that finished; a second interrupt stops the wait;
- **isolated failures**: a file that cannot be processed is reported with
  the reason, and every other file is still processed;
- **retries**: tasks are pure functions of their arguments, submitted with
  ``retries``, so the tasks of a worker that dies are run again elsewhere.

The report (one entry per file: status ``"ok"``, ``"skipped"`` or
``"failed"``, reason, seconds, output path, what was made and, for raws
developed with lens corrections, what lensfun matched and was applied) is
returned and written as JSON next to the outputs, atomically too. The file
keeps, after this run's entries, the earlier runs' entries for the folder's
other outputs (another format, other sources) and failures.

:func:`demosaic_dask` and :func:`develop_dask` process one mosaic too large
for one machine's memory as a ``dask.array``, with results identical to the
whole-image :func:`imgform_rs.demosaic` and :func:`imgform_rs.develop`
(without lens corrections, which need the whole image: develop_dask refuses them).
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from ._chunked import demosaic_dask, develop_dask
from ._imagefile import landing, partial_path, partial_stem, replace_onto

__all__ = [
    "WORKER_CONFIG",
    "BatchReport",
    "FileResult",
    "align_many",
    "demosaic_dask",
    "develop_dask",
    "develop_many",
    "local_client",
]

RETRIES = 3
"""How often a task is re-run after its worker died (not after an error in
the file: those are reported, and re-running would fail again)."""

_EXPECTED = (ValueError, TypeError, OSError)
_SUFFIX = {"png": ".png", "tiff": ".tif", "jpeg": ".jpg", "exr": ".exr"}


@dataclass(frozen=True)
class FileResult:
    """What happened to one input file."""

    source: str
    output: str
    status: str
    """``"ok"``, ``"skipped"`` (the output existed) or ``"failed"``."""
    reason: str
    seconds: float
    """Time the file took; for a skipped file, what the report of the run
    that made its output says (so a re-run keeps the record), else 0."""
    detail: str = ""
    """What was made (develop: the picture's size; align: the shifts found)."""
    note: str = ""
    """Anything else found about the file (develop: the lens correction
    matched and applied, when ``lens_correction`` is not "off")."""


@dataclass(frozen=True)
class BatchReport:
    """Per-file results, in input order, and where they were written."""

    files: list[FileResult]
    path: Path

    @property
    def failed(self) -> list[FileResult]:
        """The files that could not be processed."""
        return [f for f in self.files if f.status == "failed"]

    def count(self, status: str) -> int:
        """How many files ended with ``status``."""
        return sum(f.status == status for f in self.files)


def _distributed() -> Any:
    try:
        import distributed
    except ImportError as exc:
        raise ImportError(
            "imgform_rs.batch needs Dask, an optional dependency: pip install imgform-rs[dask]"
        ) from exc
    return distributed


WORKER_CONFIG: dict[str, Any] = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.worker.profile.enabled": False,
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.admin.tick.interval": "1s",
}
"""The Dask configuration :func:`local_client` starts its workers with, so
that a worker spends its time on the files (``benchmarks/scale_out.py``
measures each setting on 12 MP raws); ``dask.config.set(WORKER_CONFIG)``
around a ``LocalCluster``, or the same keys in the Dask configuration file
of ``dask worker``, do the same for a cluster started otherwise.

- No ``MALLOC_TRIM_THRESHOLD_``: Dask's nannies set it to 64 KiB so freed
  memory goes back to the OS at once, which also switches off glibc's
  adaptive mmap threshold: every buffer above 128 KiB of every file (the
  decoded raw, develop's intermediates, the PNG rows and zlib stream) is
  then mapped and faulted in afresh: 96k page faults per 12 MP raw
  against 48-71k, and 0.2-0.4 CPU s more per file. Unset, a worker keeps
  some freed memory for the next file, as a local loop does.
- No statistical profiler and a slower system monitor and event-loop
  check: they sample every 10, 500 and 20 ms for the dashboard, which a
  local cluster here does not start, and cost the worker's event loop
  0.15 CPU s per file against 0.035 s with these.
"""


@contextlib.contextmanager
def local_client(workers: int = 2, *, env: dict[str, str] | None = None) -> Iterator[Any]:
    """A ``distributed.Client`` on a new local cluster, closed on exit.

    Parameters
    ----------
    workers : int
        Worker processes, one thread each: the Rust kernels are parallel
        themselves (set ``RAYON_NUM_THREADS`` in ``env`` to share cores
        fairly between workers).
    env : dict, optional
        Environment variables of the worker processes.

    Notes
    -----
    The workers start with :data:`WORKER_CONFIG` (glibc's adaptive malloc
    thresholds, no dashboard samplers), as fast per file as a plain local
    loop; that configuration is set in this process while the client is
    open, so a worker the nanny restarts gets it too.
    """
    if not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an int >= 1, got {workers!r}")
    distributed = _distributed()
    import dask

    # Set for the cluster's whole life: a nanny restarting a lost worker
    # spawns it with the configuration of that moment.
    with dask.config.set(WORKER_CONFIG):
        cluster = distributed.LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            # Any free port: the scheduler serves HTTP even without a
            # dashboard, and Dask's default 8787 may be another cluster's.
            dashboard_address=":0",
            env=env or {},
        )
        try:
            with distributed.Client(cluster) as client:
                yield client
        finally:
            cluster.close()


def write_atomically(target: Path, write: Callable[[Path], Any]) -> None:
    """Calls ``write(temporary)`` then renames the file to ``target`` (through
    a symbolic link, keeping a replaced file's permission bits); the
    temporary file is removed if ``write`` fails."""
    dest = landing(target)
    tmp = partial_path(dest)
    try:
        write(tmp)
        replace_onto(tmp, dest)
    finally:
        tmp.unlink(missing_ok=True)


def _develop_file(source: Path, tmp: Path, options: dict) -> tuple[str, str]:
    from .develop import develop_to

    develop_options = dict(options)
    quality = develop_options.pop("quality", 92)
    _, (h, w), lens = develop_to(source, tmp, quality, True, develop_options)
    return f"{w}x{h}", lens


def _align_file(source: Path, tmp: Path, options: dict) -> tuple[str, str]:
    from ._png import for_png, write_png
    from .align import _colorize, describe_estimate, read_plate

    rgb, found = _colorize(read_plate(source), **options)
    write_png(tmp, for_png(rgb))
    reference = options.get("reference", "g")
    moved = ", ".join(f"{c.upper()} {describe_estimate(found[c])}" for c in "rgb" if c != reference)
    return f"{moved} onto {reference.upper()}", ""


_WORK = {"develop": _develop_file, "align": _align_file}


def run_file(kind: str, source: str, target: str, options: dict) -> FileResult:
    """One task: process ``source`` into ``target`` atomically. A pure
    function of its arguments, so Dask may run it again after a worker dies;
    errors in the file become a "failed" result, not an exception."""
    start = time.perf_counter()
    detail = note = ""

    def write(tmp: Path) -> None:
        nonlocal detail, note
        detail, note = _WORK[kind](Path(source), tmp, options)

    try:
        write_atomically(Path(target), write)
    except _EXPECTED as exc:
        # RawError messages already start with the file name.
        reason = str(exc) if str(exc).startswith(source) else f"{source}: {exc}"
        return FileResult(source, target, "failed", reason, time.perf_counter() - start)
    return FileResult(source, target, "ok", "", time.perf_counter() - start, detail, note)


def _report_path(outdir: Path, kind: str) -> Path:
    return outdir / f"imgform-{kind}-report.json"


def _earlier(outdir: Path, kind: str) -> list[FileResult]:
    """The entries of the folder's earlier report, in its order. An
    unreadable report records nothing."""
    try:
        entries = json.loads(_report_path(outdir, kind).read_text())["files"]
        return [FileResult(**entry) for entry in entries]
    except (OSError, ValueError, TypeError, KeyError):
        return []


def _skipped(source: Path, target: Path, before: dict[str, FileResult]) -> FileResult:
    """A re-run's entry for an output it kept: how the earlier run made it,
    rather than nothing (``before`` by output name, see :func:`_write_report`)."""
    earlier = before.get(target.name)
    if earlier is None or earlier.status == "failed":
        return FileResult(str(source), str(target), "skipped", "output exists", 0.0)
    return replace(
        earlier, source=str(source), output=str(target), status="skipped", reason="output exists"
    )


def _write_report(
    outdir: Path, kind: str, results: list[FileResult], earlier: list[FileResult]
) -> BatchReport:
    """The report of this run's files, written after the earlier runs'
    entries for other outputs (another format, other sources) that are
    still there or failed: a run replaced them all before.

    Every output lies in ``outdir``, so an entry is known by its output's
    name: the paths it records are spelled as each run was given them, from
    the directory it ran in (relative, absolute, through links), which no
    later run can compare or test for existence as strings."""
    path = _report_path(outdir, kind)
    ours = {Path(r.output).name for r in results}
    kept = [
        r
        for r in earlier
        if Path(r.output).name not in ours
        and (r.status == "failed" or (outdir / Path(r.output).name).exists())
    ]
    text = json.dumps({"files": [asdict(r) for r in [*results, *kept]]}, indent=1)
    write_atomically(path, lambda tmp: tmp.write_text(text + "\n"))
    return BatchReport(results, path)


def _remove_leftovers(outdir: Path, targets: Iterable[Path]) -> None:
    """Temporary files (:func:`~imgform_rs._imagefile.partial_path`) that
    workers killed mid-write left behind: one scan of the folder, not one
    per file, which for thousands of files would be quadratic."""
    wanted = {(partial_stem(t), t.suffix) for t in targets}
    for tmp in outdir.glob(".*.part-*"):
        if any((stem, tmp.suffix) in wanted for stem in _partial_stems(tmp.name)):
            tmp.unlink(missing_ok=True)


def _partial_stems(name: str) -> Iterator[str]:
    """The target stems a temporary file's name may stand for, outermost
    first: ``write_image`` writes its own temporary file beside the one a
    task writes, so a worker killed then leaves ``..x.part-A.part-B.png``
    (a hidden stem ``.x`` leaves ``..x.part-A.png`` alone)."""
    while name.startswith(".") and ".part-" in name:
        name = name[1:]
        yield name.partition(".part-")[0]


OnResult = Callable[[FileResult, int, int], None]
"""Called as ``on_result(result, done, total)`` as each file finishes."""


def _submit_all(
    client: Any,
    kind: str,
    pairs: list,
    options: dict,
    tick: Callable[[FileResult], None],
    results: list[FileResult],
) -> None:
    """Runs the pairs one task each, appending their results to ``results``
    in completion order. The tasks get absolute paths, since a scheduler's
    workers may run in another directory than the client; the results, their
    reasons too, name the paths as given.

    On ``KeyboardInterrupt`` the tasks no worker has taken are cancelled and
    those in progress are waited for and recorded, then the interrupt goes
    on: a task cannot be stopped, so a file being written at the interrupt
    would otherwise land after the report was written, missing from it. A
    second interrupt stops the wait."""
    distributed = _distributed()
    futures = {
        client.submit(
            run_file, kind, str(s.absolute()), str(t.absolute()), options, retries=RETRIES
        ): (s, t)
        for s, t in pairs
    }
    seen: set = set()

    def record(future: Any) -> None:
        seen.add(future)
        source, target = futures[future]
        try:
            result = future.result()
            reason = result.reason.replace(str(source.absolute()), str(source), 1)
            result = replace(result, source=str(source), output=str(target), reason=reason)
        except Exception as exc:  # a lost worker after all retries, an OOM kill...
            result = FileResult(str(source), str(target), "failed", f"{source}: {exc!r}", 0.0)
        results.append(result)
        tick(result)

    try:
        for future in distributed.as_completed(futures):
            record(future)
    except KeyboardInterrupt:
        left = [f for f in futures if f not in seen]
        taken = {key for keys in client.processing().values() for key in keys}
        running = [f for f in left if f.done() or f.key in taken]
        client.cancel([f for f in left if f.key not in taken and not f.done()])
        for future in distributed.as_completed(running):
            record(future)
        raise


def output_paths(sources: Iterable[Any], outdir: Any, suffix: str) -> list[tuple[Path, Path]]:
    """Each source with its output, ``outdir/<stem><suffix>``.

    Two sources with one stem (``a/x.dng`` and ``b/x.kdc``) would be written
    to one output, the later replacing the earlier or skipped as if done
    before: a ValueError names every such group, so that a batch refuses
    before it writes anything and loses no result. Stems that differ only
    in case (``X.dng``, ``x.nef``) count as one: on macOS and Windows they
    are one file.
    """
    pairs = [(Path(s), Path(outdir) / f"{Path(s).stem}{suffix}") for s in sources]
    nameless = [str(source) for source, _ in pairs if source.name in ("", ".", "..")]
    if nameless:  # ".", "..", "/": their output would be the hidden OUTDIR/.png
        raise ValueError(f"{', '.join(nameless)}: a folder, not a file; nothing was written")
    writers: dict[str, list[Path]] = {}
    for source, target in pairs:
        writers.setdefault(str(target).casefold(), []).append(source)
    named = {str(target).casefold(): target for _, target in reversed(pairs)}
    clashes = [
        f"{' and '.join(map(str, group))} -> {named[key]}"
        for key, group in writers.items()
        if len(group) > 1
    ]
    if clashes:
        raise ValueError(
            f"inputs would overwrite each other's output: {'; '.join(clashes)}; nothing was "
            "written (rename them, or run them into different folders)"
        )
    inputs = {_identity(source) for source, _ in pairs}
    onto = [f"{t}" for _, t in pairs if _identity(t) in inputs]
    if onto:
        raise ValueError(
            f"the output {', '.join(onto)} would replace an input; nothing was written "
            "(choose another output folder)"
        )
    return pairs


def _identity(path: Path) -> tuple:
    """What makes two paths one file: device and inode where the file
    exists (through links, other spellings, hard links), else the resolved
    path, case-folded as :func:`output_paths` compares stems."""
    try:
        st = path.stat()
    except OSError:
        return ("path", str(path.resolve()).casefold())
    return ("inode", st.st_dev, st.st_ino)


def output_folder(outdir: Any, *, make: bool = True) -> Path:
    """``outdir``, made if missing (unless not ``make``: a dry run). A file in
    its place, or in the place of a folder above it, is a NotADirectoryError
    saying so, where ``Path.mkdir`` says "File exists" (or, unmade, nothing)."""
    out = Path(outdir)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"the output folder {out} is a file")
    above = next((p for p in out.parents if p.exists()), None)
    if above is not None and not above.is_dir():
        raise NotADirectoryError(f"the output folder {out} lies under the file {above}")
    if make:
        out.mkdir(parents=True, exist_ok=True)
    return out


def _run_batch(
    kind: str,
    sources: Iterable[Any],
    outdir: Any,
    suffix: str,
    options: dict,
    *,
    client: Any,
    overwrite: bool,
    on_result: OnResult | None,
) -> BatchReport:
    """Skips finished files, runs the rest, writes and returns the report."""
    _distributed()
    if isinstance(sources, (str, os.PathLike)):
        raise TypeError(f"sources must be a list of paths, got the single path {sources!r}")
    pairs = output_paths(sources, outdir, suffix)
    out = output_folder(outdir)
    earlier = _earlier(out, kind)
    before = {Path(r.output).name: r for r in earlier}
    skipped = [_skipped(s, t, before) for s, t in pairs if t.exists() and not overwrite]
    todo = [(s, t) for s, t in pairs if overwrite or not t.exists()]
    counter = itertools.count(1)

    def tick(result: FileResult) -> None:
        if on_result:
            on_result(result, next(counter), len(pairs))

    for result in skipped:
        tick(result)
    done: list[FileResult] = []
    order = {str(t): i for i, (_, t) in enumerate(pairs)}

    def report() -> BatchReport:
        results = sorted(skipped + done, key=lambda r: order[r.output])
        return _write_report(out, kind, results, earlier)

    if todo:
        try:
            with contextlib.ExitStack() as stack:
                if client is None:
                    client = stack.enter_context(local_client())
                _submit_all(client, kind, todo, options, tick, done)
        except KeyboardInterrupt:
            report()  # the files that finished keep their entries
            raise
        _remove_leftovers(out, (t for _, t in todo))
    return report()


def _check_develop_options(format: str, options: dict) -> None:
    """What every file would fail for, refused before any runs: an unknown
    keyword, a format and bit depth that do not go together, a bad quality."""
    import inspect

    from ._imagefile import check_format, check_quality
    from .develop import check_bps, develop

    known = set(inspect.signature(develop).parameters) - {"source"} | {"quality"}
    unknown = sorted(set(options) - known)
    if unknown:
        raise TypeError(f"develop_many got unknown options {unknown}; it takes {sorted(known)}")
    bps = options.get("bps", 8)
    check_bps(bps)
    check_format(format, bps)
    check_quality(options.get("quality", 92))


def develop_many(
    sources: Iterable[str | os.PathLike[str]],
    outdir: str | os.PathLike[str],
    *,
    client: Any = None,
    overwrite: bool = False,
    format: str = "png",
    on_result: OnResult | None = None,
    **develop_kwargs: Any,
) -> BatchReport:
    """Develop raw files on a Dask cluster, one task per file.

    Each ``OUTDIR/<stem>.png`` (or ``.tif``, ``.jpg``, ``.exr``), with its colour
    profile and the raw's EXIF (:func:`imgform_rs.develop_file`), is written atomically; existing
    outputs are kept unless ``overwrite``; the report is also written to
    ``OUTDIR/imgform-develop-report.json``.

    Parameters
    ----------
    sources : iterable of path
        Raw files (anything :func:`imgform_rs.load_raw` reads), distinct stems.
    outdir : path
        Created if missing.
    client : distributed.Client, optional
        Where to run; by default a local cluster of 2 worker processes,
        closed afterwards.
    overwrite : bool
        Process files whose output exists (default: skip them).
    format : {"png", "tiff", "jpeg", "exr"}
    on_result : callable, optional
        ``on_result(result, done, total)`` as each file finishes (a progress bar).
    **develop_kwargs
        Options of :func:`imgform_rs.develop` (``demosaic``, ``bps``, ...) and
        ``quality`` for JPEG.

    Returns
    -------
    BatchReport
        One :class:`FileResult` per source, in input order.

    Raises
    ------
    ImportError
        Without the ``dask`` extra.
    ValueError
        For an unknown format, or sources with one file name (stem), which
        would write one output: the message names them (before any work).
    OSError
        For an output folder that cannot be made, a file in its place.

    Examples
    --------
    >>> import tempfile
    >>> import numpy as np
    >>> from distributed import Client
    >>> from imgform_rs.dng import write_dng
    >>> with (
    ...     tempfile.TemporaryDirectory() as d,
    ...     Client(processes=False, dashboard_address=":0") as client,
    ... ):
    ...     cfa = (np.arange(32 * 32) % 2000 + 100).astype(np.uint16).reshape(32, 32)
    ...     write_dng(f"{d}/a.dng", cfa, "RGGB", white_level=4095)
    ...     report = develop_many([f"{d}/a.dng"], f"{d}/out", client=client)
    ...     again = develop_many([f"{d}/a.dng"], f"{d}/out", client=client)
    >>> [f.status for f in report.files], [f.status for f in again.files]
    (['ok'], ['skipped'])
    """
    if format not in _SUFFIX:
        raise ValueError(f'format must be "png", "tiff", "jpeg" or "exr", got {format!r}')
    _check_develop_options(format, develop_kwargs)
    return _run_batch(
        "develop",
        sources,
        outdir,
        _SUFFIX[format],
        develop_kwargs,
        client=client,
        overwrite=overwrite,
        on_result=on_result,
    )


def align_many(
    plates: Iterable[str | os.PathLike[str]],
    outdir: str | os.PathLike[str],
    *,
    client: Any = None,
    overwrite: bool = False,
    on_result: OnResult | None = None,
    **align_kwargs: Any,
) -> BatchReport:
    """Colourise Prokudin-Gorskii plates on a Dask cluster, one task per plate.

    What ``imgform align`` does for each plate (:func:`imgform_rs.read_plate`,
    :func:`imgform_rs.colorize_plate`, a PNG, 16-bit for 16-bit scans), with
    the guarantees of :func:`develop_many`; the report goes to
    ``OUTDIR/imgform-align-report.json``.

    Parameters
    ----------
    plates : iterable of path
        8-bit JPG or 16-bit TIFF scans, B, G, R stacked top to bottom.
    outdir : path
    client, overwrite, on_result
        As for :func:`develop_many`.
    **align_kwargs
        Options of :func:`imgform_rs.colorize_plate` (``reference``,
        ``metric``, ``max_shift``, ``features``).

    Returns
    -------
    BatchReport
    """
    return _run_batch(
        "align",
        plates,
        outdir,
        ".png",
        align_kwargs,
        client=client,
        overwrite=overwrite,
        on_result=on_result,
    )
