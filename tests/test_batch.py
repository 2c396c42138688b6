"""Scale-out on Dask: chunked demosaic/develop identical to the whole-image
calls, and file batches on a real 2-process LocalCluster."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from imgform_rs import (
    BAYER_DEMOSAIC_METHODS,
    DEMOSAIC_METHODS,
    XTRANS_DEMOSAIC_METHODS,
    demosaic,
    demosaic_halo,
    develop,
    load_raw,
    simulate_sensor,
)
from imgform_rs.cli import main
from imgform_rs.dng import write_dng
from imgform_rs.lens import LensMatch, LensProfile

da = pytest.importorskip("dask.array")
distributed = pytest.importorskip("distributed")
batch = pytest.importorskip("imgform_rs.batch")
iio = pytest.importorskip("imageio.v3")

PATTERNS = ["RGGB", "BGGR", "GRBG", "GBRG", "XTRANS"]
DTYPES = [np.uint8, np.uint16, np.float32]


def test_the_core_never_imports_dask():
    code = (
        "import sys, numpy as np, imgform_rs, imgform_rs.batch, imgform_rs.cli\n"
        "raw = np.arange(64, dtype=np.uint16).reshape(8, 8)\n"
        "imgform_rs.demosaic(raw, 'RGGB', 'bilinear')\n"
        "imgform_rs.cli.build_parser()\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_without_dask_the_error_names_the_extra():
    code = (
        "import sys\n"
        "sys.modules['dask'] = sys.modules['distributed'] = None\n"
        "import numpy as np\n"
        "from imgform_rs import batch\n"
        "for call in (lambda: batch.demosaic_dask(np.zeros((4, 4)), 'RGGB'),\n"
        "             lambda: batch.develop_many([], '.')):\n"
        "    try:\n"
        "        call()\n"
        "    except ImportError as exc:\n"
        "        print(exc)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    lines = out.stdout.strip().splitlines()
    assert len(lines) == 2
    assert all("pip install imgform-rs[dask]" in line for line in lines)


def accepts(method: str, pattern: str) -> bool:
    try:
        demosaic(np.zeros((6, 6), np.uint8), pattern, method)
    except ValueError:
        return False
    return True


def split(n: int, sizes: list[int]) -> tuple[int, ...]:
    """Chunk sizes along an axis of length n, cycling through ``sizes``."""
    out, i = [], 0
    while sum(out) < n:
        out.append(min(sizes[i % len(sizes)], n - sum(out)))
        i += 1
    return tuple(out)


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow], print_blob=True
)
@given(
    method=st.sampled_from(DEMOSAIC_METHODS),
    pattern=st.sampled_from(PATTERNS),
    dtype=st.sampled_from(DTYPES),
    shape=st.tuples(st.integers(6, 70), st.integers(6, 70)),
    row_chunks=st.lists(st.integers(1, 40), min_size=1, max_size=4),
    col_chunks=st.lists(st.integers(1, 40), min_size=1, max_size=4),
    seed=st.integers(0, 2**32 - 1),
)
def test_demosaic_dask_is_demosaic_bit_for_bit(
    method, pattern, dtype, shape, row_chunks, col_chunks, seed
):
    if not accepts(method, pattern):
        with pytest.raises(ValueError, match="X-Trans"):
            batch.demosaic_dask(da.zeros((12, 12), dtype=dtype), pattern, method)
        return
    rng = np.random.default_rng(seed)
    # A narrow range with one darker and one brighter pixel somewhere: the
    # clamping methods clamp to the whole mosaic's range, which most chunks
    # do not hold.
    raw = (rng.integers(30, 200, shape) / (255.0 if dtype == np.float32 else 1)).astype(dtype)
    for value in (0, 250 / (255.0 if dtype == np.float32 else 1)):
        raw[rng.integers(shape[0]), rng.integers(shape[1])] = value
    chunks = (split(shape[0], row_chunks), split(shape[1], col_chunks))
    lazy = batch.demosaic_dask(da.from_array(raw, chunks=chunks), pattern, method)
    got = lazy.compute(scheduler="synchronous")
    expected = demosaic(raw, pattern, method)
    assert got.dtype == expected.dtype
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("level", [None, 4095.0, 65535.0])
def test_demosaic_dask_takes_the_white_level_of_the_whole_mosaic(level):
    # 12-bit samples in uint16; the brightest sits in one chunk only, yet every
    # chunk infers the mosaic's bit depth from it, as the whole image does.
    rng = np.random.default_rng(7)
    raw = rng.integers(100, 1500, (40, 52)).astype(np.uint16)
    raw[31, 45] = 4000
    chunked = da.from_array(raw, chunks=(14, 18))
    lazy = batch.demosaic_dask(chunked, "GRBG", "quality", white_level=level)
    expected = demosaic(raw, "GRBG", "quality", white_level=level)
    np.testing.assert_array_equal(lazy.compute(scheduler="synchronous"), expected)
    if level is None:
        np.testing.assert_array_equal(expected, demosaic(raw, "GRBG", "quality", white_level=4095))


def test_every_method_declares_a_halo():
    for method in DEMOSAIC_METHODS:
        for pattern in PATTERNS:
            methods = XTRANS_DEMOSAIC_METHODS if pattern == "XTRANS" else BAYER_DEMOSAIC_METHODS
            if method in methods:
                assert demosaic_halo(method, pattern) >= 1
            else:  # refused as demosaic refuses it
                with pytest.raises(ValueError, match=f'method "{method}" supports'):
                    demosaic_halo(method, pattern)
    with pytest.raises(ValueError, match="unknown demosaicing method"):
        demosaic_halo("sharpest", "RGGB")
    with pytest.raises(TypeError, match="method must be a str"):
        demosaic_halo(None, "RGGB")


def test_demosaic_dask_chunks_sit_on_the_cfa_period():
    raw = da.zeros((100, 90), dtype=np.uint16, chunks=(33, 17))
    out = batch.demosaic_dask(raw, "XTRANS", "bilinear")
    for axis in (0, 1):
        assert all(c % 6 == 0 for c in out.chunks[axis][:-1]), out.chunks


def test_demosaic_dask_refuses_bad_input():
    with pytest.raises(TypeError, match=r"dask\.array"):
        batch.demosaic_dask(np.zeros((8, 8), np.uint16), "RGGB")
    with pytest.raises(TypeError, match=r"integer or float.*bool"):
        batch.demosaic_dask(da.zeros((8, 8), dtype=bool), "RGGB")
    negative = da.from_array(np.arange(-1, 63, dtype=np.int32).reshape(8, 8), chunks=4)
    with pytest.raises(ValueError, match=r"0\.\.65535.*got -1\.\.62"):
        batch.demosaic_dask(negative, "RGGB")


@pytest.mark.parametrize(
    ("dtype", "bad"),
    [
        (np.float32, {(10, 10): np.nan}),
        # The first in row-major order is in the third chunk column, the
        # first chunk's one on a later row.
        (np.float32, {(30, 5): np.inf, (25, 50): np.nan}),
        (np.float64, {(60, 85): -np.inf}),
        # Beyond 2^100, where sums of neighbours would overflow float32.
        (np.float32, {(30, 5): 3e38, (25, 50): -1e31}),
        (np.float64, {(40, 41): 1e35}),
    ],
)
def test_demosaic_dask_names_a_non_finite_sample_where_the_whole_mosaic_has_it(dtype, bad):
    raw = np.random.default_rng(0).random((61, 86)).astype(dtype)
    for (y, x), value in bad.items():
        raw[y, x] = value
    with pytest.raises(ValueError) as whole:
        demosaic(raw, "RGGB", "rcd")
    # Before: when computed, the row and column within a chunk (4, 10).
    with pytest.raises(ValueError, match=re.escape(str(whole.value))):
        batch.demosaic_dask(da.from_array(raw, chunks=21), "RGGB", "rcd")


@pytest.mark.parametrize(
    ("shape", "pattern"),
    [((1, 1), "RGGB"), ((1, 7), "GRBG"), ((7, 1), "RGGB"), ((1, 40), "BGGR"), ((5, 30), "XTRANS")],
)
def test_demosaic_dask_refuses_a_mosaic_smaller_than_one_cfa_tile(shape, pattern):
    raw = np.arange(np.prod(shape), dtype=np.uint16).reshape(shape)
    with pytest.raises(ValueError, match="at least"):
        demosaic(raw, pattern)
    # Before: "zero-size array to reduction operation fmin".
    tile = "6x6" if pattern == "XTRANS" else "2x2"
    message = f"one full CFA tile, {tile} pixels, got {shape}"
    with pytest.raises(ValueError, match=re.escape(message)):
        batch.demosaic_dask(da.from_array(raw, chunks=4), pattern)


def test_demosaic_dask_asks_for_unknown_chunk_sizes_to_be_computed():
    raw = np.random.default_rng(1).integers(0, 4096, (61, 40)).astype(np.uint16)
    rows = np.arange(61) % 3 > 0
    lazy = da.from_array(raw, chunks=20)[da.from_array(rows, chunks=20)]
    # Before: "cannot convert float NaN to integer".
    with pytest.raises(ValueError, match=r"unknown chunk sizes.*compute_chunk_sizes\(\)"):
        batch.demosaic_dask(lazy, "RGGB")
    got = batch.demosaic_dask(lazy.compute_chunk_sizes(), "RGGB", "malvar2004")
    np.testing.assert_array_equal(got.compute(), demosaic(raw[rows], "RGGB", "malvar2004"))


@pytest.mark.parametrize("dtype", [np.int32, np.uint64, np.float64])
def test_demosaic_dask_converts_other_dtypes_as_demosaic_does(dtype):
    rng = np.random.default_rng(5)
    raw = rng.integers(0, 4096, (40, 36))
    raw = (raw / 4095 if dtype == np.float64 else raw).astype(dtype)
    lazy = batch.demosaic_dask(da.from_array(raw, chunks=(14, 11)), "GBRG", "rcd")
    got = lazy.compute(scheduler="synchronous")
    assert got.dtype == dtype
    np.testing.assert_array_equal(got, demosaic(raw, "GBRG", "rcd"))
    with pytest.raises(ValueError, match=r"\(H, W\)"):
        batch.demosaic_dask(da.zeros((8, 8, 3), dtype=np.uint16), "RGGB")
    with pytest.raises(ValueError, match="unknown demosaicing method"):
        batch.demosaic_dask(da.zeros((8, 8), dtype=np.uint16), "RGGB", "sharpest")


def scene(h: int, w: int, seed: int) -> np.ndarray:
    """A smooth, colourful linear scene with a few clipped highlights."""
    y, x = np.mgrid[0:h, 0:w] / max(h, w)
    rgb = np.stack([0.5 + 0.4 * np.sin(7 * x + seed), 0.4 + 0.3 * y, 0.3 + 0.2 * x * y], -1)
    rgb[h // 3 : h // 3 + 3, w // 4 : w // 4 + 5] = 1.2
    return rgb.astype(np.float32)


def write_raw(path, h=64, w=72, seed=0, pattern="RGGB", neutral=(0.5, 1.0, 0.7)) -> str:
    cfa = simulate_sensor(scene(h, w, seed), pattern, seed=seed)
    write_dng(path, cfa, pattern, white_level=4095 + 64, black_level=64, as_shot_neutral=neutral)
    return str(path)


@pytest.mark.parametrize(
    ("pattern", "options"),
    [
        ("RGGB", {"white_balance": "auto", "bps": 16, "demosaic": "best"}),
        ("GBRG", {"white_balance": "camera", "bps": 8, "orientation": "none"}),
        ("XTRANS", {"white_balance": "auto", "bps": "float", "demosaic": "bilinear"}),
    ],
)
def test_develop_dask_is_develop_bit_for_bit(tmp_path, pattern, options):
    raw = load_raw(write_raw(tmp_path / "a.dng", 90, 100, seed=3, pattern=pattern))
    for flip, chunks in [(0, 16), (5, (37, 29)), (3, 200)]:
        flipped = dataclasses.replace(raw, flip=flip)
        got = batch.develop_dask(flipped, chunks=chunks, **options).compute(scheduler="synchronous")
        np.testing.assert_array_equal(got, develop(flipped, **options))


def test_develop_dask_refuses_what_it_cannot_do(tmp_path):
    raw = load_raw(write_raw(tmp_path / "a.dng"))
    with pytest.raises(TypeError, match="RawImage"):
        batch.develop_dask(raw.cfa)
    with pytest.raises(ValueError, match="pixel_aspect"):
        batch.develop_dask(dataclasses.replace(raw, pixel_aspect=0.5))


def lens_profile() -> LensProfile:
    """Strong vignetting and barrel distortion, centred on the image."""
    return LensProfile(
        "test", "test", 1.0, 1.0, 1.5, (0.0, 0.0), 50.0, 2.8, 10.0,
        ("poly3", (0.05,)), None, (-0.5, 0.1, 0.0),
    )  # fmt: skip


def test_develop_dask_refuses_lens_corrections_it_cannot_make(tmp_path):
    raw = load_raw(write_raw(tmp_path / "a.dng"))
    # Before: each chunk corrected as if centred on itself, a different picture.
    for lens in (lens_profile(), LensMatch(lens_profile(), "test"), "auto"):
        with pytest.raises(ValueError, match=r"whole image's coordinates.*use develop"):
            batch.develop_dask(raw, chunks=24, lens_correction=lens)
    for off in ("off", None):
        got = batch.develop_dask(raw, chunks=24, lens_correction=off)
        np.testing.assert_array_equal(got.compute(scheduler="synchronous"), develop(raw))


@pytest.mark.parametrize(
    "options",
    [
        {"bps": 12},
        {"color": "nope"},
        {"tone": "nope"},
        {"white_balance": "bogus"},
        {"white_balance": (1.0, 0.0, 1.0)},
        {"exposure": 1e9},
        {"exposure": "bright"},
        {"highlights": "keep"},
        {"demosaic": 3},
        {"demosaic": "sharpest"},
    ],
)
def test_develop_dask_refuses_what_develop_refuses_when_the_array_is_made(tmp_path, options):
    raw = load_raw(write_raw(tmp_path / "a.dng"))
    with pytest.raises((TypeError, ValueError)) as whole:
        develop(raw, **options)
    # Before: a lazy array that failed in a worker, at compute().
    with pytest.raises(whole.type, match=re.escape(str(whole.value))):
        batch.develop_dask(raw, chunks=24, **options)


def test_develop_dask_names_the_options_it_takes(tmp_path):
    raw = load_raw(write_raw(tmp_path / "a.dng"))
    with pytest.raises(TypeError, match=r"unknown options \['foo'\]; it takes \['bps', 'color'"):
        batch.develop_dask(raw, foo=1)
    with pytest.raises(ValueError, match=r'lens_correction="off" only, got \'bogus\''):
        batch.develop_dask(raw, lens_correction="bogus")
    for zero in (0, (0, 8)):  # a ZeroDivisionError from Dask before
        with pytest.raises(ValueError, match=r"chunks must be sizes > 0"):
            batch.develop_dask(raw, chunks=zero)


# --- file batches on a real cluster ---


@pytest.fixture(scope="module")
def client():
    """One 2-process cluster for the whole module (starting one costs seconds)."""
    with batch.local_client(2, env={"RAYON_NUM_THREADS": "1"}) as c:
        yield c


@pytest.fixture(scope="module")
def raws(tmp_path_factory):
    folder = tmp_path_factory.mktemp("raws")
    paths = [write_raw(folder / f"shot{i}.dng", seed=i) for i in range(4)]
    corrupt = folder / "corrupt.dng"
    corrupt.write_bytes(b"II*\x00" + bytes(200))
    return paths, str(corrupt)


def outputs(folder) -> list[str]:
    return sorted(os.listdir(folder))


def worker_settings(client) -> set[tuple]:
    """What WORKER_CONFIG changes, as every worker process sees it."""

    def read():
        import dask

        return (
            os.environ.get("MALLOC_TRIM_THRESHOLD_"),
            dask.config.get("distributed.worker.profile.enabled"),
            dask.config.get("distributed.admin.tick.interval"),
        )

    return set(client.run(read).values())


def test_local_workers_keep_glibc_malloc_tuning_and_no_profiler(client):
    # Dask's nanny would set MALLOC_TRIM_THRESHOLD_=65536 and profile every 10 ms.
    assert worker_settings(client) == {(None, False, "1s")}


def test_develop_many_matches_develop_reports_the_corrupt_file_and_resumes(tmp_path, client, raws):
    paths, corrupt = raws
    out = tmp_path / "out"
    report = batch.develop_many([*paths, corrupt], out, client=client, bps=16, format="tiff")
    assert [f.status for f in report.files] == ["ok"] * 4 + ["failed"]
    assert "corrupt.dng" in report.failed[0].reason
    for path, f in zip(paths, report.files, strict=False):
        np.testing.assert_array_equal(iio.imread(f.output), develop(path, bps=16))
        assert f.seconds > 0
    saved = json.loads(report.path.read_text())["files"]
    assert [f["status"] for f in saved] == ["ok"] * 4 + ["failed"]
    assert outputs(out) == sorted([*(f"shot{i}.tif" for i in range(4)), report.path.name])
    stamps = [os.stat(f.output).st_mtime_ns for f in report.files[:4]]
    again = batch.develop_many(paths, out, client=client, bps=16, format="tiff")
    assert [f.status for f in again.files] == ["skipped"] * 4
    assert [os.stat(f.output).st_mtime_ns for f in again.files] == stamps
    # The re-run's report keeps how each output was made, run after run.
    made = [(f.seconds, f.detail) for f in report.files[:4]]
    assert [(f.seconds, f.detail) for f in again.files] == made
    third = batch.develop_many(paths, out, client=client, bps=16, format="tiff")
    saved = json.loads(third.path.read_text())["files"]
    # The file also keeps the first run's failure, which these runs left out.
    assert [(f["status"], f["seconds"], f["detail"]) for f in saved[:4]] == [
        ("skipped", *m) for m in made
    ]
    assert [(f["status"], f["source"]) for f in saved[4:]] == [("failed", corrupt)]
    # A run in another format keeps the TIFFs' entries in the file, and the
    # next TIFF run still knows how they were made (before, each run's
    # report replaced the last).
    png = batch.develop_many(paths[:1], out, client=client, format="png")
    saved = json.loads(png.path.read_text())["files"]
    assert [Path(f["output"]).suffix for f in saved] == [".png"] + [".tif"] * 5
    fourth = batch.develop_many(paths, out, client=client, bps=16, format="tiff")
    assert [(f.seconds, f.detail) for f in fourth.files] == made


def test_an_interrupted_batch_reports_the_files_that_finished(tmp_path, client, raws):
    """Ctrl-C on a cluster run wrote no report: the files done were lost to it."""
    paths, _ = raws
    out = tmp_path / "out"
    seen = []

    def interrupt(result, done, total):
        seen.append(result.output)
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        batch.develop_many(paths, out, client=client, on_result=interrupt)
    saved = json.loads((out / "imgform-develop-report.json").read_text())["files"]
    assert sorted(f["output"] for f in saved) == sorted(seen)
    assert all(f["status"] == "ok" and Path(f["output"]).exists() for f in saved)


def test_an_interrupt_waits_for_the_files_in_progress_and_drops_the_rest(tmp_path, client):
    """The file a worker was writing at the interrupt landed after the report
    was written, missing from it; the files no worker had taken ran on."""
    first = write_raw(tmp_path / "shot0.dng", 1600, 2400, seed=1)
    paths = [first] + [shutil.copy(first, tmp_path / f"shot{i}.dng") for i in range(1, 8)]
    out = tmp_path / "out"

    def interrupt(result, done, total):
        if done == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        batch.develop_many(paths, out, client=client, on_result=interrupt)
    saved = json.loads((out / "imgform-develop-report.json").read_text())["files"]
    time.sleep(1.5)  # a file still being written would land by now
    written = sorted(p.name for p in out.glob("shot*"))
    assert sorted(Path(f["output"]).name for f in saved) == written
    assert all(f["status"] == "ok" for f in saved)
    # The other worker's file was in progress; at most two files a worker
    # are ever taken (Dask's queueing), so some of the eight never ran.
    assert 1 < len(written) < len(paths)


def test_the_command_line_says_where_an_interrupted_cluster_run_left_its_report(
    tmp_path, raws, monkeypatch, capsys
):
    """It was a traceback from Dask's as_completed."""
    import contextlib

    from imgform_rs import cli

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_cluster", lambda args: contextlib.nullcontext())
    monkeypatch.setattr(batch, "develop_many", interrupted)
    paths, _ = raws
    out = tmp_path / "out"
    assert cli.main(["develop", paths[0], "-o", str(out), "--workers", "1"]) == 130
    report = out / "imgform-develop-report.json"
    assert capsys.readouterr().err.startswith(f"imgform develop: interrupted; {report} lists")


def test_the_report_knows_its_outputs_however_their_paths_were_spelled(
    tmp_path, client, raws, monkeypatch
):
    """Entries were compared by path as typed, and tested for existence from
    the directory of the later run: a run from elsewhere dropped them, and
    absolute paths gave one output two entries."""
    paths, _ = raws
    out = tmp_path / "out"
    monkeypatch.chdir(tmp_path)
    batch.develop_many([paths[0]], "out", client=client)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    batch.develop_many([paths[1]], out, client=client)
    again = batch.develop_many([paths[0]], out.absolute(), client=client)
    saved = json.loads(again.path.read_text())["files"]
    assert sorted((Path(f["output"]).name, f["status"]) for f in saved) == [
        ("shot0.png", "skipped"),
        ("shot1.png", "ok"),
    ]
    assert saved[0]["seconds"] > 0  # how the first run made it, kept


def test_develop_many_writes_what_develop_file_writes(tmp_path, client, raws):
    import io
    from pathlib import Path

    from PIL import Image, ImageCms

    from imgform_rs import develop_file

    paths, _ = raws
    options = dict(quality=80, exposure="auto", color="display_p3")
    out = tmp_path / "out"
    report = batch.develop_many(paths[:1], out, client=client, format="jpeg", **options)
    assert [f.status for f in report.files] == ["ok"]
    want = develop_file(paths[0], tmp_path / "one.jpg", **options)
    assert Path(report.files[0].output).read_bytes() == want.read_bytes()
    with Image.open(want) as im:
        profile = ImageCms.ImageCmsProfile(io.BytesIO(im.info["icc_profile"]))
    assert ImageCms.getProfileDescription(profile).startswith("Display P3, srgb curve")


def test_a_batch_removes_the_partial_files_of_its_own_outputs_only(tmp_path, client, raws):
    paths, _ = raws
    out = tmp_path / "out"
    out.mkdir()
    dead = [out / ".shot0.part-0123abcd.png", out / ".shot1.part-4567.png"]
    foreign = [out / ".shot0.part-89ab.tif", out / ".notours.part-cdef.png"]
    for f in dead + foreign:
        f.write_bytes(b"half a file")
    report = batch.develop_many(paths[:2], out, client=client)
    assert [f.status for f in report.files] == ["ok", "ok"]
    assert outputs(out) == sorted(
        [f.name for f in foreign] + ["shot0.png", "shot1.png", report.path.name]
    )
    # The command line without a cluster, too.
    for f in dead:
        f.write_bytes(b"half a file")
    (out / "shot0.png").unlink()
    (out / "shot1.png").unlink()
    assert main(["develop", *paths[:2], "-o", str(out)]) == 0
    assert outputs(out) == sorted(
        [f.name for f in foreign] + ["shot0.png", "shot1.png", report.path.name]
    )


def test_a_name_the_file_system_takes_is_written_and_its_partial_file_found(tmp_path, client, raws):
    """A 240-byte stem: the partial names that the batch and write_image add
    ~40 bytes to were refused (ENAMETOOLONG) before partial_stem cut them."""
    from imgform_rs._imagefile import partial_stem

    paths, _ = raws
    long = tmp_path / ("写真" * 40 + Path(paths[0]).suffix)
    shutil.copy(paths[0], long)
    out = tmp_path / "out"
    out.mkdir()
    target = out / (long.stem + ".png")
    dead = out / f".{partial_stem(target)}.part-0123abcd.png"
    dead.write_bytes(b"half a file")
    report = batch.develop_many([long], out, client=client)
    assert [f.status for f in report.files] == ["ok"]
    assert outputs(out) == sorted([target.name, report.path.name])


def test_inputs_with_one_output_are_refused_before_anything_is_written(
    tmp_path, client, raws, capsys
):
    """a/shot0.dng and b/shot0.kdc would both write OUT/shot0.png: the batch
    and the command line on a cluster refuse them, naming them, as the
    command line without one does (tests/test_develop.py)."""
    paths, _ = raws
    twin = tmp_path / "b" / "shot0.kdc"
    twin.parent.mkdir()
    shutil.copyfile(paths[0], twin)
    out = tmp_path / "out"
    clash = re.escape(f"{paths[0]} and {twin} -> {out / 'shot0.png'}")
    for many in (batch.develop_many, batch.align_many):
        with pytest.raises(ValueError, match=clash):
            many([paths[0], paths[1], str(twin)], out, client=client)
    scheduler = client.scheduler.address
    for command in ("develop", "align"):
        argv = [command, paths[0], str(twin), "-o", str(out), "--scheduler", scheduler]
        assert main([*argv, "--overwrite"]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"imgform {command}: inputs would overwrite each other's output")
        assert re.search(clash, err) and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize(
    ("options", "exc", "match"),
    [
        ({"bps": 12}, ValueError, 'bps must be 8, 16 or "float", got 12'),
        ({"format": "jpeg", "bps": 16}, ValueError, "JPEG files take bps 8, got bps=16"),
        ({"colour": "srgb"}, TypeError, r"unknown options \['colour'\]"),
        ({"quality": 0}, ValueError, "quality"),
    ],
)
def test_develop_many_refuses_what_every_file_would_fail_for_before_any_runs(
    tmp_path, options, exc, match
):
    with pytest.raises(exc, match=match):
        batch.develop_many([str(tmp_path / "a.dng")], tmp_path / "out", **options)
    assert not (tmp_path / "out").exists()


def test_names_that_differ_only_in_case_are_one_output(tmp_path):
    # One file on macOS and Windows: refused everywhere, so no result is lost.
    with pytest.raises(ValueError, match=re.escape(f"a/X.dng and b/x.nef -> {tmp_path / 'X.png'}")):
        batch.output_paths(["a/X.dng", "b/x.nef"], tmp_path, ".png")
    pairs = batch.output_paths(["a/X.dng", "b/Y.nef"], tmp_path, ".png")
    assert [t.name for _, t in pairs] == ["X.png", "Y.png"]


def test_an_output_folder_that_is_a_file_is_one_clear_error(tmp_path, client, raws, capsys):
    paths, _ = raws
    out = tmp_path / "out"
    out.write_bytes(b"a file, not a folder")
    with pytest.raises(NotADirectoryError, match=f"the output folder {re.escape(str(out))} is"):
        batch.develop_many(paths[:1], out, client=client)
    scheduler = client.scheduler.address
    assert main(["develop", paths[0], "-o", str(out), "--scheduler", scheduler]) == 2
    assert capsys.readouterr().err == f"imgform develop: the output folder {out} is a file\n"


def test_a_scheduler_the_cli_cannot_reach_is_one_clear_error(tmp_path, raws, capsys):
    import dask

    paths, _ = raws
    out = tmp_path / "out"
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        code = main(["develop", paths[0], "-o", str(out), "--scheduler", "tcp://127.0.0.1:1"])
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("imgform develop: Timed out trying to connect to tcp://127.0.0.1:1")
    assert err.count("\n") == 1
    assert not out.exists()  # no empty output folder left behind
    # An address Dask cannot parse is one line too, not a traceback.
    assert main(["develop", paths[0], "-o", str(tmp_path), "--scheduler", "bogus"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("imgform develop: ") and err.count("\n") == 1, err


@pytest.mark.slow
def test_a_killed_worker_loses_no_file_and_leaves_no_partial_file(tmp_path, client):
    paths = [write_raw(tmp_path / f"big{i}.dng", 600, 800, seed=i) for i in range(8)]
    pids = list(client.run(os.getpid).values())
    killed = []

    def kill_once(result, done, total):
        if not killed:
            os.kill(pids[0], signal.SIGKILL)
            killed.append(pids[0])

    out = tmp_path / "out"
    report = batch.develop_many(paths, out, client=client, on_result=kill_once)
    client.wait_for_workers(2)
    assert worker_settings(client) == {(None, False, "1s")}  # the new one too
    assert killed
    assert killed[0] not in client.run(os.getpid).values()  # the nanny started a new one
    assert [f.status for f in report.files] == ["ok"] * 8
    assert outputs(out) == sorted([*(f"big{i}.png" for i in range(8)), report.path.name])
    for path, f in zip(paths[:2], report.files, strict=False):
        np.testing.assert_array_equal(iio.imread(f.output), develop(path))


def plate(h: int, w: int, seed: int) -> np.ndarray:
    """A synthetic plate: B, G, R exposures of a textured scene stacked,
    each a few pixels off."""
    rng = np.random.default_rng(seed)
    base = rng.random((h + 20, w + 20))
    base = (base + np.roll(base, 1, 0) + np.roll(base, 1, 1)) / 3
    parts = [
        base[10 + dy : 10 + dy + h, 10 + dx : 10 + dx + w] for dy, dx in [(2, -3), (0, 0), (-4, 1)]
    ]
    return (np.concatenate(parts) * 255).astype(np.uint8)


def test_cli_align_and_develop_on_a_scheduler(tmp_path, client, raws, capsys):
    paths, corrupt = raws
    scheduler = client.scheduler.address
    plates = []
    for i in range(2):
        plates.append(str(tmp_path / f"plate{i}.png"))
        iio.imwrite(plates[-1], plate(60, 64, i))
    assert main(["align", *plates, "-o", str(tmp_path / "local")]) == 0
    assert main(["align", *plates, "-o", str(tmp_path / "dask"), "--scheduler", scheduler]) == 0
    for i in range(2):
        local = iio.imread(tmp_path / "local" / f"plate{i}.png")
        np.testing.assert_array_equal(iio.imread(tmp_path / "dask" / f"plate{i}.png"), local)
    code = main(
        ["develop", paths[0], corrupt, "-o", str(tmp_path / "dev"), "--scheduler", scheduler]
    )
    assert code == 1
    err = capsys.readouterr().err
    assert "corrupt.dng" in err
    assert "1 of 2 raws failed" in err
    assert (tmp_path / "dev" / "shot0.png").is_file()


def test_cli_on_a_scheduler_reports_each_files_lens_as_a_local_run_does(tmp_path, client, capsys):
    """--lens auto on a cluster: each file's line and the JSON report say
    what lensfun matched and applied, as ``imgform develop`` without one does."""
    pytest.importorskip("lensfunpy")
    cfa = (1200 + np.arange(64 * 96) % 700).astype(np.uint16).reshape(64, 96)
    kit = dict(make="Canon", model="Canon EOS 550D", lens="EF-S 18-55mm f/3.5-5.6 IS")
    known, unknown = tmp_path / "kit.dng", tmp_path / "unknown.dng"
    write_dng(known, cfa, "RGGB", white_level=4095, focal_length=18, f_number=5.6, **kit)
    write_dng(unknown, cfa, "RGGB", white_level=4095)
    sources = [str(known), str(unknown)]
    lines = {}
    for where, extra in (("local", []), ("dask", ["--scheduler", client.scheduler.address])):
        out = tmp_path / where
        assert main(["develop", *sources, "-o", str(out), "--lens", "auto", *extra]) == 0
        printed = capsys.readouterr().out.splitlines()
        # Each file's line but for the time it took (the cluster adds "report: ...").
        lines[where] = sorted(
            re.sub(r" in [0-9.]+ s -> ", " -> ", line) for line in printed if " s -> " in line
        )
    assert len(lines["local"]) == 2
    assert lines["dask"] == [
        line.replace(str(tmp_path / "local"), str(tmp_path / "dask")) for line in lines["local"]
    ]
    report = json.loads((tmp_path / "dask" / "imgform-develop-report.json").read_text())
    notes = {os.path.basename(f["source"]): f["note"] for f in report["files"]}
    assert notes["kit.dng"].startswith(
        "lens correction: Canon / Canon EF-S 18-55mm f/3.5-5.6 IS on Canon / Canon EOS 550D "
        "at 18 mm f/5.6: distortion ptlens, TCA poly3, vignetting pa"
    )
    assert notes["unknown.dng"].startswith("lens correction: none (camera ")
    np.testing.assert_array_equal(
        iio.imread(tmp_path / "dask" / "kit.png"), iio.imread(tmp_path / "local" / "kit.png")
    )
