"""The ``imgform`` command line."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

# Sample data beside the checkout (shared/ is not part of the project).
SAMPLE_PLATE = Path("../shared/data/pg/cathedral.jpg")
SAMPLE_RAW = Path("../shared/data/raw/canon_eos_kiss_x4_magiclantern_colorchart.dng")


def _demo(args: argparse.Namespace) -> int:
    from .demo import run

    if args.plate is None:
        plate = SAMPLE_PLATE if SAMPLE_PLATE.is_file() else None
    elif Path(args.plate).is_file():
        plate = Path(args.plate)
    else:
        print(f"imgform demo: no plate file at {args.plate}", file=sys.stderr)
        return 2
    camera_raw = SAMPLE_RAW if SAMPLE_RAW.is_file() else None
    try:
        from .batch import output_folder

        output_folder(args.out, make=False)  # a file named as the folder
        if plate is not None:
            from .align import read_plate

            read_plate(plate)  # a bad plate found now, not after the other figures
        written = run(Path(args.out), plate=plate, camera_raw=camera_raw, overwrite=args.overwrite)
    except (OSError, ValueError) as exc:  # an output that exists, an out that is a file
        print(f"imgform demo: {exc}", file=sys.stderr)
        return 2
    for path in written:
        print(f"wrote {path}")
    return 0


def _progress(done: int, total: int, unit: str = "plates") -> None:
    """A one-line bar on stderr, drawn only on a terminal (logs stay clean)."""
    if total < 2 or not sys.stderr.isatty():
        return
    width = 30
    filled = width * done // total
    end = "\n" if done == total else ""
    sys.stderr.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} {unit}{end}")
    sys.stderr.flush()


def _clustered(args: argparse.Namespace) -> bool:
    """Whether ``--scheduler`` or ``--workers`` sends the files to Dask."""
    return bool(args.scheduler or args.workers)


def _cluster(args: argparse.Namespace):
    """A Dask client for ``--scheduler`` or ``--workers`` (closed on exit)."""
    from .batch import local_client

    if args.scheduler:
        from distributed import Client

        return Client(args.scheduler)
    return local_client(args.workers)


def _on_cluster(args: argparse.Namespace, many, sources: list[str], unit: str, **options) -> int:
    """Runs a batch on Dask, printing each file as it finishes."""
    command = f"imgform {args.command}"

    def report(result, done: int, total: int) -> None:
        if result.status == "ok":
            line = _file_line(
                result.source, result.detail, result.seconds, result.output, result.note
            )
            print(line)
        elif result.status == "skipped":
            print(f"{result.source}: {result.output} exists, kept (use --overwrite to replace it)")
        else:
            print(f"{command}: {result.reason}", file=sys.stderr)
        _progress(done, total, unit)

    try:
        with _cluster(args) as client:
            batch = many(
                sources,
                args.out,
                client=client,
                overwrite=args.overwrite,
                on_result=report,
                **options,
            )
    except (ImportError, OSError, ValueError) as exc:  # no Dask; a bad or lost scheduler
        print(f"{command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        from .batch import _report_path

        report_file = _report_path(Path(args.out), args.command)
        print(
            f"{command}: interrupted; {report_file} lists the files finished, those in "
            "progress at the interrupt included",
            file=sys.stderr,
        )
        return 130
    failed = len(batch.failed)
    if failed:
        print(f"{command}: {failed} of {len(sources)} {unit} failed", file=sys.stderr)
    print(f"report: {batch.path}")
    return 1 if failed else 0


def _outputs(
    args: argparse.Namespace,
    sources: list[str],
    suffix: str,
    *,
    dry_run: bool = False,
    on_cluster: bool = False,
) -> list[tuple[Path, Path]] | None:
    """Each input with its output file, the output folder made (checked
    only, for a dry run, and for a cluster, whose batch makes it once the
    scheduler answers: one that cannot be reached leaves no empty folder);
    None, after saying why on stderr, for inputs that would write one output
    or a folder that cannot be made. Checked before any file is processed, on
    a cluster too, so that such a run writes nothing."""
    from .batch import output_folder, output_paths

    try:
        pairs = output_paths(sources, args.out, suffix)
        output_folder(args.out, make=not (dry_run or on_cluster))
    except (ValueError, OSError) as exc:
        print(f"imgform {args.command}: {exc}", file=sys.stderr)
        return None
    return pairs


def _align(args: argparse.Namespace) -> int:
    import time

    pairs = _outputs(args, args.plates, ".png", on_cluster=_clustered(args))
    if pairs is None:
        return 2
    if _clustered(args):
        from .batch import align_many

        options = {
            "reference": args.reference,
            "metric": args.metric,
            "max_shift": args.max_shift,
            "features": args.features,
            "motion": args.motion,
            "white_balance": args.white_balance,
            "auto_contrast": args.auto_contrast,
        }
        return _on_cluster(args, align_many, args.plates, "plates", **options)

    from ._png import for_png, write_png
    from .align import _colorize, describe_estimate, read_plate
    from .batch import write_atomically

    failed = 0
    for i, (path, target) in enumerate(pairs, start=1):
        if target.exists() and not args.overwrite:
            print(f"{path}: {target} exists, kept (use --overwrite to replace it)")
        else:
            start = time.perf_counter()
            try:
                rgb, found = _colorize(
                    read_plate(path),
                    reference=args.reference,
                    metric=args.metric,
                    max_shift=args.max_shift,
                    features=args.features,
                    motion=args.motion,
                    white_balance=args.white_balance,
                    auto_contrast=args.auto_contrast,
                )
                write_atomically(target, lambda tmp, rgb=rgb: write_png(tmp, for_png(rgb)))
            except (ValueError, TypeError, OSError) as exc:
                failed += 1
                print(f"imgform align: {path}: {exc}", file=sys.stderr)
            else:
                took = time.perf_counter() - start
                moved = ", ".join(
                    f"{c.upper()} {describe_estimate(found[c])}"
                    for c in "rgb"
                    if c != args.reference
                )
                print(f"{path}: {moved} onto {args.reference.upper()} in {took:.2f} s -> {target}")
        _progress(i, len(args.plates))
    if failed:
        print(f"imgform align: {failed} of {len(args.plates)} plates failed", file=sys.stderr)
    return 1 if failed else 0


def _srgb_to_linear(img: np.ndarray) -> np.ndarray:
    """An 8- or 16-bit (or float) sRGB image as linear float32, (H, W, 3)."""
    import numpy as np

    scales = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}
    if img.dtype not in scales and img.dtype.kind != "f":
        # Other integers have no agreed white (an int32 TIFF read as 0..1 printed white).
        raise ValueError(f"film takes 8- or 16-bit or float images, got {img.dtype}")
    v = img.astype(np.float32) / np.float32(scales.get(img.dtype, 1.0))
    if v.ndim == 2:
        v = v[..., None]
    if v.ndim != 3 or v.shape[2] not in (1, 2, 3, 4):
        raise ValueError(f"film takes grey, RGB or RGBA images, got shape {img.shape}")
    # Grey (and alpha) repeated to three channels; RGB(A) without its alpha.
    v = np.repeat(v[..., :1], 3, axis=-1) if v.shape[2] < 3 else v[..., :3]
    v = np.maximum(v, 0.0)  # a float image's negatives are no light (and the power's NaN)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _film(args: argparse.Namespace) -> int:
    import time

    from . import film
    from ._png import for_png, read_image, write_png
    from .batch import write_atomically

    try:
        stock, paper = film._simulation_stocks(args.stock, args.paper)
    except (ValueError, OSError) as exc:
        print(f"imgform film: {exc}", file=sys.stderr)
        return 2
    pairs = _outputs(args, args.images, ".png")
    if pairs is None:
        return 2
    failed = 0
    for i, (path, target) in enumerate(pairs, start=1):
        if target.exists() and not args.overwrite:
            print(f"{path}: {target} exists, kept (use --overwrite to replace it)")
            _progress(i, len(pairs), "images")
            continue
        start = time.perf_counter()
        try:
            rgb = _srgb_to_linear(read_image(path))
            result = film.simulate(
                rgb,
                stock,
                paper=paper,
                exposure_ev=args.ev,
                couplers=not args.no_couplers,
            )
            write_atomically(target, lambda tmp, result=result: write_png(tmp, for_png(result)))
        except Exception as exc:  # imageio raises many types for bad files
            failed += 1
            reason = (str(exc).splitlines() or [type(exc).__name__])[0]
            print(f"imgform film: {path}: {reason}", file=sys.stderr)
        else:
            took = time.perf_counter() - start
            print(f"{path}: {stock.name}, {args.ev:+g} EV in {took:.2f} s -> {target}")
        _progress(i, len(args.images), "images")
    if failed:
        print(f"imgform film: {failed} of {len(args.images)} images failed", file=sys.stderr)
    return 1 if failed else 0


def _develop_options(args: argparse.Namespace) -> dict:
    """The :func:`imgform_rs.develop` keywords the command line set."""
    return {
        "demosaic": args.demosaic,
        "white_balance": args.white_balance,
        "color": args.color,
        "tone": args.tone,
        "exposure": args.exposure,
        "highlights": args.highlights,
        "bps": args.bps,
        "orientation": args.orientation,
        "lens_correction": args.lens,
    }


_SUFFIX = {"png": ".png", "tiff": ".tif", "jpeg": ".jpg", "exr": ".exr"}


def _develop_one(path: Path, target: Path, args: argparse.Namespace) -> str:
    """Develop one raw into ``target``; returns the line to print."""
    import time

    from .develop import develop_to

    start = time.perf_counter()
    options = _develop_options(args)
    _, (h, w), lens = develop_to(path, target, args.quality, args.overwrite, options)
    took = time.perf_counter() - start
    return _file_line(str(path), f"{w}x{h}", took, str(target), lens)


def _file_line(source: str, detail: str, seconds: float, target: str, note: str) -> str:
    """One processed file's line, the same with or without a cluster."""
    return f"{source}: {detail} in {seconds:.2f} s -> {target}" + (f"; {note}" if note else "")


def _develop(args: argparse.Namespace) -> int:
    from concurrent.futures import ThreadPoolExecutor

    from ._imagefile import check_exr, check_format
    from .batch import _remove_leftovers
    from .develop import _tone_for

    try:
        check_format(args.format, args.bps)
        if args.format == "exr":
            check_exr(args.color, _tone_for(args.color, args.tone), None)
        if args.lens == "auto":
            from .lens import lens_database

            lens_database()  # ImportError without lensfunpy, before any file
    except (ValueError, ImportError) as exc:
        print(f"imgform develop: {exc}", file=sys.stderr)
        return 2
    pairs = _outputs(
        args,
        args.raws,
        _SUFFIX[args.format],
        dry_run=args.dry_run,
        on_cluster=_clustered(args),
    )
    if pairs is None:
        return 2
    if args.dry_run:
        return _develop_dry_run(args, pairs)
    if _clustered(args):
        from .batch import develop_many

        options = {**_develop_options(args), "format": args.format, "quality": args.quality}
        return _on_cluster(args, develop_many, args.raws, "raws", **options)

    todo, failed = [], 0
    for path, target in pairs:
        if target.exists() and not args.overwrite:
            print(f"{path}: {target} exists, kept (use --overwrite to replace it)")
        else:
            todo.append((path, target))
    # Threads suffice: decoding and the Rust pipeline release the GIL.
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = [(path, pool.submit(_develop_one, path, target, args)) for path, target in todo]
        reported = 0
        try:
            for path, future in futures:
                failed += _print_developed(path, future)
                reported += 1
                _progress(reported, len(futures), "raws")
        except KeyboardInterrupt:
            # Files not started are dropped; those being developed finish
            # (threads cannot be stopped), each written whole or not at all,
            # and said as the others were.
            pool.shutdown(wait=False, cancel_futures=True)
            left = [(p, f) for p, f in futures[reported:] if not f.cancelled()]
            print(
                f"imgform develop: interrupted; finishing the {len(left)} file(s) in progress",
                file=sys.stderr,
            )
            for path, future in left:
                _print_developed(path, future)
            return 130
    # Partial files a killed earlier run left of these outputs (as on Dask).
    _remove_leftovers(Path(args.out), (target for _, target in todo))
    if failed:
        print(f"imgform develop: {failed} of {len(args.raws)} raws failed", file=sys.stderr)
    return 1 if failed else 0


def _print_developed(path: Path, future) -> int:
    """Prints one developed file's line, or its failure; 1 if it failed."""
    try:
        print(future.result())
    except (ValueError, TypeError, OSError) as exc:
        # RawError messages already start with the file name.
        reason = str(exc) if str(exc).startswith(str(path)) else f"{path}: {exc}"
        print(f"imgform develop: {reason}", file=sys.stderr)
        return 1
    return 0


def _develop_dry_run(args: argparse.Namespace, pairs: list[tuple[Path, Path]]) -> int:
    """Lists what ``imgform develop`` would write, and with which options,
    touching nothing (no folder is made, no raw is decoded)."""
    options = ", ".join(f"{k}={v!r}" for k, v in _develop_options(args).items())
    print(f"develop options: {options}; {args.format}, quality {args.quality}")
    failing = 0
    for path, target in pairs:  # in the order a run decides
        if target.exists() and not args.overwrite:
            print(f"{path}: {target} exists, would keep it")
        elif not path.is_file():
            failing += 1
            why = "not a regular file" if path.exists() else "no such file"
            print(f"{path}: {why}, would fail")
        else:
            print(f"{path}: would write {target}")
    return 1 if failing else 0


def _white_balance(text: str) -> str | tuple[float, float, float]:
    """A white-balance name, or R,G,B multipliers."""
    from .develop import WHITE_BALANCES

    if text in WHITE_BALANCES:
        return text
    try:
        rgb = tuple(float(v) for v in text.split(","))
    except ValueError:
        rgb = ()
    if len(rgb) != 3 or not all(v > 0 and v < float("inf") for v in rgb):
        raise argparse.ArgumentTypeError(
            f"must be one of {', '.join(WHITE_BALANCES)} or three multipliers R,G,B > 0, "
            f"got {text!r}"
        )
    return (rgb[0], rgb[1], rgb[2])


def _exposure(text: str) -> str | float:
    """ "auto" or a number of stops that :func:`imgform_rs.develop` takes."""
    from .develop import MAX_EXPOSURE

    if text == "auto":
        return text
    try:
        stops = float(text)
    except ValueError:
        stops = float("nan")
    if not abs(stops) <= MAX_EXPOSURE:
        raise argparse.ArgumentTypeError(
            f'must be "auto" or a number of stops from {-MAX_EXPOSURE:g} to {MAX_EXPOSURE:g}, '
            f"got {text!r}"
        )
    return stops


def _quality(text: str) -> int:
    from ._imagefile import check_quality

    try:
        return check_quality(int(text))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"must be an int from 1 to 100, got {text!r}") from exc


def _bps(text: str) -> int | str:
    if text in ("8", "16"):
        return int(text)
    if text == "float":
        return text
    raise argparse.ArgumentTypeError(f'must be 8, 16 or "float", got {text!r}')


def _count(least: int):
    """An argparse type: an int of at least ``least``, refused saying so (a
    ValueError let through makes argparse say "invalid count value")."""

    def count(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = least - 1
        if value < least:
            raise argparse.ArgumentTypeError(f"must be an int >= {least}, got {text!r}")
        return value

    return count


def _ev(text: str) -> float:
    """A film exposure change that :func:`imgform_rs.film.simulate` takes."""
    from .film import _gain

    try:
        value = float(text)
        _gain(value)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).replace("exposure_ev ", "")) from None
    return value


def _add_cluster_options(parser: argparse.ArgumentParser) -> None:
    """--scheduler / --workers: run the files on Dask (pip install imgform-rs[dask])."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help="run one task per file on this Dask scheduler's workers",
    )
    where.add_argument(
        "--workers",
        type=_count(1),
        metavar="N",
        help="run one task per file on a local Dask cluster of N worker processes",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="imgform",
        description="Rust-accelerated image formation: geometry, optics, sensors, demosaicing.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    demo = sub.add_parser(
        "demo", help="render the built-in sample scene through every camera model"
    )
    demo.add_argument("-o", "--out", default="out", help="output folder (default: out)")
    demo.add_argument(
        "--plate",
        help=f"a Prokudin-Gorskii scan to colourise (default: {SAMPLE_PLATE}, when present)",
    )
    demo.add_argument(
        "--overwrite", action="store_true", help="replace existing outputs (default: keep them)"
    )
    demo.set_defaults(run=_demo)
    align = sub.add_parser(
        "align",
        help="colourise Prokudin-Gorskii plates (B, G, R stacked top to bottom)",
        description="Align the three exposures of each plate and write OUTDIR/<name>.png "
        "(16-bit for 16-bit scans). Shifts are (dy, dx) in the np.roll convention.",
    )
    align.add_argument("plates", nargs="+", metavar="PLATE", help="8-bit JPG or 16-bit TIFF scans")
    align.add_argument("-o", "--out", required=True, metavar="OUTDIR", help="output folder")
    align.add_argument("--metric", default="ncc", choices=["ncc", "ssd", "cosine"])
    align.add_argument("--reference", default="g", choices=["r", "g", "b"])
    align.add_argument(
        "--max-shift",
        type=_count(0),
        default=None,
        help="largest |dy|, |dx| searched (default: 20%% of a channel's shorter side, >= 15 "
        "where the crop leaves room)",
    )
    align.add_argument(
        "--features",
        default="auto",
        choices=["auto", "intensity", "gradient"],
        help="what is correlated (default auto: gradient magnitudes for every motion but a "
        "translation, intensities for a translation)",
    )
    align.add_argument(
        "--motion",
        default="translation",
        choices=["translation", "euclidean", "similarity", "affine"],
        help="motion model between the exposures (default: translation, the exact shift search)",
    )
    align.add_argument(
        "--white-balance", action="store_true", help="grey-world balance of the result"
    )
    align.add_argument(
        "--auto-contrast", action="store_true", help="stretch the result to the full range"
    )
    align.add_argument(
        "--overwrite", action="store_true", help="replace existing outputs (default: keep them)"
    )
    _add_cluster_options(align)
    align.set_defaults(run=_align)
    films = sub.add_parser(
        "film",
        help="photograph images on simulated colour film (negative + print, or a slide)",
        description="Take each 8/16-bit sRGB image as the scene, expose it on a film stock, "
        "develop it, print a negative on paper (balanced for mid grey), and write what one "
        "sees under D65 to OUTDIR/<name>.png (16-bit sRGB).",
    )
    films.add_argument("images", nargs="+", metavar="IMAGE", help="PNG, JPEG or TIFF files")
    films.add_argument("-o", "--out", required=True, metavar="OUTDIR", help="output folder")
    films.add_argument(
        "--stock",
        default="generic-negative",
        help="a shipped stock name or a stock .json file (default: generic-negative)",
    )
    films.add_argument("--paper", default=None, help="printing paper (default: the generic one)")
    films.add_argument("--ev", type=_ev, default=0.0, help="exposure change in stops")
    films.add_argument("--no-couplers", action="store_true", help="switch DIR couplers off")
    films.add_argument(
        "--overwrite", action="store_true", help="replace existing outputs (default: keep them)"
    )
    films.set_defaults(run=_film)
    from .demosaic import DEMOSAIC_METHODS
    from .develop import COLORS, DEFAULT_DEMOSAIC, HIGHLIGHTS, TONES

    dev = sub.add_parser(
        "develop",
        help="develop raw files (DNG, CR2, NEF, ...) to PNG, TIFF, JPEG or EXR",
        description="Decode each raw with LibRaw and develop it (by default: camera white "
        "balance, brightened as LibRaw does, sRGB) to OUTDIR/<name>.png, .tif, .jpg or .exr, "
        "with the colour space's ICC profile (EXR: chromaticities) and the raw's EXIF. Files "
        "that cannot be developed are reported with the reason; the others are still "
        "developed, and the exit status is 1.",
    )
    dev.add_argument("raws", nargs="+", metavar="IN", help="raw files")
    dev.add_argument("-o", "--out", required=True, metavar="OUTDIR", help="output folder")
    dev.add_argument("--demosaic", default=DEFAULT_DEMOSAIC, choices=DEMOSAIC_METHODS)
    dev.add_argument(
        "--white-balance",
        type=_white_balance,
        default="camera",
        metavar="{camera,daylight,auto,none,R,G,B}",
        help="as shot (default), the camera's daylight, grey world, none, or multipliers",
    )
    dev.add_argument(
        "--exposure",
        type=_exposure,
        default="auto",
        metavar="{auto,STOPS}",
        help="auto (default): LibRaw's brightening, the brightest 1%% to white; "
        "or a change in stops (0 keeps the file's exposure)",
    )
    dev.add_argument("--highlights", default="clip", choices=HIGHLIGHTS)
    dev.add_argument("--color", default="srgb", choices=COLORS, help="output colour space")
    dev.add_argument(
        "--tone",
        default="auto",
        choices=("auto", *TONES),
        help="transfer curve (default: the colour space's own)",
    )
    dev.add_argument("--orientation", default="auto", choices=["auto", "none"])
    dev.add_argument(
        "--lens",
        default="off",
        choices=["auto", "off"],
        help="auto: correct distortion, lateral CA and vignetting with the lensfun profile "
        "of the file's camera and lens (needs lensfunpy; each file's line says what was "
        "matched and applied); off (default): no lens corrections",
    )
    dev.add_argument(
        "--format",
        default="png",
        choices=list(_SUFFIX),
        help="png (default), tiff, jpeg, or exr (linear float: --bps float --tone linear; "
        "needs OpenEXR)",
    )
    dev.add_argument(
        "--quality", type=_quality, default=92, help="JPEG quality, 1-100 (default: 92)"
    )
    dev.add_argument(
        "--bps",
        type=_bps,
        default=8,
        metavar="{8,16,float}",
        help="bits per sample (float: 32-bit float TIFF or EXR, for linear output)",
    )
    dev.add_argument("-j", "--jobs", type=_count(1), default=1, help="files developed at once")
    dev.add_argument(
        "--overwrite", action="store_true", help="replace existing outputs (default: keep them)"
    )
    dev.add_argument(
        "--dry-run",
        action="store_true",
        help="list what would be written, and do nothing (no raw is decoded: exit 1 if an "
        "input is missing or not a file)",
    )
    _add_cluster_options(dev)
    dev.set_defaults(run=_develop)
    return parser


def main(argv: list[str] | None = None) -> int:
    # A file name that is not valid in the terminal's encoding (Latin-1
    # bytes under UTF-8) is printed with escapes rather than failing its file.
    for stream in (sys.stdout, sys.stderr):
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    args = build_parser().parse_args(argv)
    try:
        return int(args.run(args))
    except KeyboardInterrupt:
        # Each output is written whole or not at all (write_atomically).
        print(f"imgform {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
