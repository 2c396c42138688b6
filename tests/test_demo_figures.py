"""The demo's spectral figures: the chart's error measure and Figure 4a's plot."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import imgform_rs.spectral as sp
from imgform_rs._spectral_figures import (
    CURVE_COLOURS,
    GLASSES,
    chart_errors,
    focal_shift_plot,
    srgb_decode,
    srgb_encode,
)

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    pytest.importorskip("colour")


def _painted_chart(wl, colours):
    """A chart image (linear sRGB) whose patches are exactly ``colours``."""
    _, boxes = sp.colorchecker_scene(wl, np.ones(len(wl)), patch=20, gap=4)
    image = np.zeros((boxes[-1][0].stop + 4, boxes[-1][1].stop + 4, 3))
    for (ys, xs), c in zip(boxes, colours, strict=True):
        image[ys, xs] = c
    return image, boxes


def test_chart_errors_vanish_for_the_charts_own_colours_at_any_exposure():
    wl = sp.wavelengths()
    _, want, _ = chart_errors(*_painted_chart(wl, np.full((24, 3), 0.5)), wl)
    image, boxes = _painted_chart(wl, 0.4 * want)
    de, _, gain = chart_errors(image, boxes, wl)
    assert gain == pytest.approx(2.5)
    assert de.max() < 1e-9
    # A patch off by a shift in red is the one that shows an error.
    image[boxes[3]] *= [1.2, 1.0, 1.0]
    de, _, _ = chart_errors(image, boxes, wl)
    assert np.argmax(de) == 3 and de[3] > 1 and np.delete(de, 3).max() < 1e-9


def test_srgb_encoding_round_trips_every_8_bit_level():
    levels = np.arange(256, dtype=np.uint8)
    np.testing.assert_array_equal(srgb_encode(srgb_decode(levels)), levels)


def test_figure_4a_draws_each_glass_the_more_dispersive_the_lower_at_400_nm():
    plot = focal_shift_plot(size=(560, 340))
    assert plot.shape == (340, 560, 3)
    # Just inside the axes' left edge (400 nm): each curve's pixels, top to
    # bottom, come in the order of falling Abbe number.
    column = plot[:, 62]
    rows = [np.flatnonzero((column == c).all(axis=1)).mean() for c in CURVE_COLOURS]
    abbe = [v_d for _, v_d in GLASSES.values()]
    assert abbe == sorted(abbe, reverse=True)
    assert rows[0] < rows[1] < rows[2]


def test_the_demo_writes_all_its_pictures_or_none_and_keeps_what_is_there(
    tmp_path, monkeypatch, capsys
):
    from imgform_rs import cli, demo

    def pictures(out, log, plate, camera_raw):
        return [demo.write_png(out / n, np.zeros((2, 2), np.uint8)) for n in ("a.png", "b.png")]

    monkeypatch.setattr(demo, "_render_all", pictures)
    out = tmp_path / "out"
    assert cli.main(["demo", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["a.png", "b.png"]
    (out / "a.png").write_bytes(b"mine")
    assert cli.main(["demo", "--out", str(out)]) == 2
    assert "b.png exist (use --overwrite" in capsys.readouterr().err
    assert (out / "a.png").read_bytes() == b"mine"
    assert sorted(p.name for p in out.iterdir()) == ["a.png", "b.png"]  # no hidden folder left
    assert cli.main(["demo", "--out", str(out), "--overwrite"]) == 0
    assert (out / "a.png").read_bytes().startswith(b"\x89PNG")


@pytest.mark.parametrize("case", ["file as folder", "under a file", "bad plate"])
def test_the_demo_command_refuses_bad_arguments_in_one_line_before_rendering(
    tmp_path, capsys, monkeypatch, case
):
    """A folder under a file and an unreadable plate were tracebacks, the
    plate's after ~15 s of rendering, leaving an empty folder."""
    from imgform_rs import cli, demo

    def render(*args, **kwargs):
        raise AssertionError("rendering started")

    monkeypatch.setattr(demo, "run", render)
    (tmp_path / "scene.png").write_bytes(b"a file")
    (tmp_path / "plate.jpg").write_bytes(b"not a JPEG")
    args = {
        "file as folder": ["-o", str(tmp_path / "scene.png")],
        "under a file": ["-o", str(tmp_path / "scene.png" / "sub")],
        "bad plate": ["-o", str(tmp_path / "out"), "--plate", str(tmp_path / "plate.jpg")],
    }[case]
    assert cli.main(["demo", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("imgform demo: ") and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plate.jpg", "scene.png"]
