"""Files a photographer keeps: JPEG, PNG and TIFF with ICC profiles and EXIF."""

from __future__ import annotations

import datetime as dt
import io
import os
import struct
from dataclasses import replace

import numpy as np
import pytest
import tifffile
from PIL import Image, ImageCms, ImageOps

import imgform_rs as ig
from conftest import shared_path
from imgform_rs._exif import exif_bytes
from imgform_rs._icc import icc_profile
from imgform_rs._png import read_image
from imgform_rs.colorspace import COLOR_SPACES
from imgform_rs.develop import _orient
from imgform_rs.dng import write_dng

RAW_DIR = shared_path("data/raw")
SHOT = ig.ShotInfo(
    make="Canon",
    model="Canon EOS Kiss X4",
    lens="EF-S18-55mm f/3.5-5.6 IS",
    iso=400,
    exposure_time=1 / 125,
    f_number=5.6,
    focal_length=35.0,
    taken=dt.datetime(2026, 11, 27, 10, 30, 5),
    artist="A. Photographer",
)


def description(icc: bytes) -> str:
    return ImageCms.getProfileDescription(ImageCms.ImageCmsProfile(io.BytesIO(icc))).strip()


def ifd_entries(tiff: bytes, offset: int) -> dict[int, tuple[int, int, bytes]]:
    """Tag -> (TIFF type, count, the entry's 4 value/offset bytes) of the IFD
    at ``offset`` of a TIFF structure (EXIF without its Exif\\0\\0), read
    here with struct rather than by Pillow, which hides the types."""
    order = "<" if tiff[:2] == b"II" else ">"
    (count,) = struct.unpack_from(order + "H", tiff, offset)
    entries = (struct.unpack_from(order + "HHI4s", tiff, offset + 2 + 12 * i) for i in range(count))
    return {tag: (kind, n, value) for tag, kind, n, value in entries}


def rgb(dtype, h=24, w=32, seed=0):
    values = np.random.default_rng(seed).random((h, w, 3))
    if dtype == np.float32:
        return values.astype(np.float32)
    return (values * np.iinfo(dtype).max).astype(dtype)


@pytest.mark.parametrize(
    ("name", "dtype"),
    [
        ("a.png", np.uint8),
        ("a.png", np.uint16),
        ("a.tif", np.uint8),
        ("a.tiff", np.uint16),
        ("a.tif", np.float32),
    ],
)
def test_lossless_files_keep_every_sample_and_carry_profile_and_exif(tmp_path, name, dtype):
    img = rgb(dtype)
    path = ig.write_image(tmp_path / name, img, color="display_p3", exif=exif_bytes(SHOT, 6, True))
    if path.suffix == ".png":
        with Image.open(path) as im:
            info, exif, read = im.info, im.getexif(), np.asarray(im)
        if dtype == np.uint16:
            # Pillow reads 16-bit RGB as 8 bits; OpenCV keeps them (as BGR).
            cv2 = pytest.importorskip("cv2")
            read = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)[..., ::-1]
        np.testing.assert_array_equal(read, img)
        assert description(info["icc_profile"]) == "Display P3, srgb curve (imgform-rs)"
        assert exif[271] == "Canon" and exif[274] == 1 and exif[306] == "2026:11:27 10:30:05"
        sub = exif.get_ifd(0x8769)
        assert sub[42036] == SHOT.lens and sub[34855] == 400
        assert float(sub[33434]) == pytest.approx(1 / 125) and float(sub[33437]) == 5.6
    else:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            np.testing.assert_array_equal(page.asarray(), img)
            tags = {t.name: t.value for t in page.tags.values()}
        assert description(tags["InterColorProfile"]) == "Display P3, srgb curve (imgform-rs)"
        assert tags["Make"] == "Canon" and tags["Model"] == "Canon EOS Kiss X4"
        assert tags["DateTime"] == "2026:11:27 10:30:05" and tags["Artist"] == SHOT.artist
        assert tags["Orientation"] == 1


@pytest.mark.parametrize("name", ["a.jpg", "a.png", "a.tif"])
def test_text_beyond_ascii_keeps_its_utf8_bytes(tmp_path, name):
    """Pillow wrote every non-ASCII character as "?" (and re-wrote a caller's
    UTF-8 so), and tifffile refused it: the bytes now pass as they are."""
    shot = replace(SHOT, make="Cámara", artist="José Müller", lens="Objectif ƒ/1.8")
    path = ig.write_image(tmp_path / name, rgb(np.uint8), exif=exif_bytes(shot, 0, True))
    theirs = Image.Exif()
    theirs[315] = "Zoë".encode()  # a caller's EXIF, as exiftool writes UTF-8
    again = ig.write_image(tmp_path / f"b{path.suffix}", rgb(np.uint8), exif=theirs.tobytes())
    with Image.open(path) as im, Image.open(again) as other:
        exif, raw, caller = im.getexif(), im.info.get("exif"), other.getexif()
    # Pillow reads every text tag as Latin-1: its bytes are the file's.
    text = {tag: exif[tag].encode("latin-1").decode() for tag in (271, 315)}
    assert text == {271: "Cámara", 315: "José Müller"}
    assert caller[315].encode("latin-1").decode() == "Zoë"
    if raw is not None:  # JPEG and PNG carry the Exif IFD, whose LensModel is ASCII
        tiff = raw.removeprefix(b"Exif\0\0")
        order = "<" if tiff[:2] == b"II" else ">"
        (ifd0,) = struct.unpack_from(order + "I", tiff, 4)
        (sub,) = struct.unpack(order + "I", ifd_entries(tiff, ifd0)[0x8769][2])
        kind, count, _ = ifd_entries(tiff, sub)[42036]
        assert (kind, count) == (2, len(shot.lens.encode()) + 1)
        assert exif.get_ifd(0x8769)[42036].encode("latin-1").decode() == shot.lens


@pytest.mark.parametrize("name", ["a.png", "a.tif"])
@pytest.mark.parametrize("dtype", [">u2", ">f4"])
def test_big_endian_samples_are_written_as_the_values_they_hold(tmp_path, name, dtype):
    """They were refused as not being the uint16 or float32 they are."""
    img = rgb(np.dtype(dtype).newbyteorder("=").type, 6, 8)
    if name == "a.png" and img.dtype.kind == "f":
        img = (img * 65535).astype(np.uint16)  # PNG writes floats as 16 bits
    swapped = img.astype(img.dtype.newbyteorder(">"))
    path = ig.write_image(tmp_path / name, swapped, tone="linear")
    back = tifffile.imread(path) if name == "a.tif" else np.asarray(read_image(path))
    np.testing.assert_array_equal(back, img)


def one_byte_exif(ifd0: dict[int, tuple[int, bytes]], sub: dict[int, tuple[int, bytes]]) -> bytes:
    """Little-endian EXIF of tags ``{tag: (type, bytes)}`` of one-byte types,
    IFD0 then the Exif IFD, each IFD's values stored after it."""

    def ifd(entries, at, sub_at=None):
        count = len(entries) + (sub_at is not None)
        data_at = at + 2 + 12 * count + 4
        rows, data = [], b""
        for tag, (kind, value) in entries.items():
            rows.append(struct.pack("<HHII", tag, kind, len(value), data_at + len(data)))
            data += value + b"\0" * (len(value) % 2)
        if sub_at is not None:
            rows.append(struct.pack("<HHII", 0x8769, 4, 1, sub_at))
        rows.sort(key=lambda row: struct.unpack_from("<H", row)[0])  # by tag
        return struct.pack("<H", count) + b"".join(rows) + struct.pack("<I", 0) + data

    size = len(ifd(ifd0, 8, 0))
    return b"Exif\0\0II*\0" + struct.pack("<I", 8) + ifd(ifd0, 8, 8 + size) + ifd(sub, 8 + size)


@pytest.mark.parametrize("name", ["a.jpg", "a.png"])
def test_a_callers_exif_keeps_the_types_of_its_byte_tags(tmp_path, name):
    """Pillow loads tags without their types: an UNDEFINED UserComment or
    CFAPattern came out BYTE (or, for a while, ASCII when it ended in NUL),
    and text Pillow does not know (UniqueCameraModel) came out BYTE."""
    given = one_byte_exif(
        {271: (2, b"Canon\0"), 50708: (2, b"My Cam\0")},
        {37510: (7, b"ASCII\0\0\0hi\0"), 41730: (7, b"\0\2\0\2\0\1\1\0"), 37500: (1, b"ab\0")},
    )
    path = ig.write_image(tmp_path / name, rgb(np.uint8), exif=given)
    with Image.open(path) as im:
        tiff = im.info["exif"].removeprefix(b"Exif\0\0")
    ifd0 = ifd_entries(tiff, struct.unpack_from("<I", tiff, 4)[0])
    sub = ifd_entries(tiff, struct.unpack("<I", ifd0[0x8769][2])[0])
    assert (ifd0[271][0], ifd0[50708][0]) == (2, 2)
    assert (sub[37510][0], sub[41730][0], sub[37500][0]) == (7, 7, 1)


def test_exif_numbers_are_rationals_and_the_exif_ifd_has_its_version(tmp_path):
    """CIPA DC-008: ExposureTime, FNumber and FocalLength are RATIONAL (type
    5), and the Exif IFD must carry ExifVersion (UNDEFINED, 4 bytes)."""
    # LibRaw reports float32s: they are written as the camera's fractions.
    single = replace(
        SHOT, exposure_time=float(np.float32(1 / 125)), f_number=float(np.float32(5.6))
    )
    for shot in (SHOT, single):
        path = ig.write_image(
            tmp_path / "a.jpg", rgb(np.uint8), exif=exif_bytes(shot, 0, True), overwrite=True
        )
        with Image.open(path) as im:
            tiff = im.info["exif"].removeprefix(b"Exif\0\0")
        order = "<" if tiff[:2] == b"II" else ">"
        (first,) = struct.unpack_from(order + "I", tiff, 4)
        pointer = ifd_entries(tiff, first)[0x8769][2]
        sub = ifd_entries(tiff, struct.unpack(order + "I", pointer)[0])
        for tag, fraction in ((33434, (1, 125)), (33437, (28, 5)), (37386, (35, 1))):
            kind, count, value = sub[tag]
            assert (kind, count) == (5, 1)
            (offset,) = struct.unpack(order + "I", value)
            assert struct.unpack_from(order + "II", tiff, offset) == fraction
        assert sub[36864] == (7, 4, b"0232")


def exif_ifd(path) -> tuple[str, dict[int, tuple[int, int, bytes]]]:
    """The byte order and the Exif IFD's entries of a JPEG or PNG, with
    their TIFF types."""
    with Image.open(path) as im:
        tiff = im.info["exif"].removeprefix(b"Exif\0\0")
    order = "<" if tiff[:2] == b"II" else ">"
    (first,) = struct.unpack_from(order + "I", tiff, 4)
    pointer = ifd_entries(tiff, first)[0x8769][2]
    return order, ifd_entries(tiff, struct.unpack(order + "I", pointer)[0])


@pytest.mark.parametrize(
    ("name", "color", "tone", "space"),
    [
        ("a.jpg", "srgb", "auto", 1),
        ("a.png", "srgb", "srgb", 1),
        ("a.jpg", "display_p3", "auto", 0xFFFF),  # no Exif value but sRGB's
        ("a.png", "srgb", "linear", 0xFFFF),  # sRGB primaries, not its curve
    ],
)
def test_the_exif_ifd_describes_the_written_image(tmp_path, name, color, tone, space):
    """Exif 2.32's tags of the image itself: ColorSpace, PixelXDimension,
    PixelYDimension, FlashpixVersion and, for JPEG (compressed),
    ComponentsConfiguration Y Cb Cr; the shot's tags stay."""
    path = ig.write_image(
        tmp_path / name,
        rgb(np.uint8, h=24, w=32),
        color=color,
        tone=tone,
        exif=exif_bytes(SHOT, 0, True),
    )
    order, sub = exif_ifd(path)
    assert sub[40961][:2] == (3, 1) and sub[40961][2][:2] == struct.pack(order + "H", space)
    assert [sub[t][2][:2] for t in (40962, 40963)] == [
        struct.pack(order + "H", 32),
        struct.pack(order + "H", 24),
    ]
    assert sub[40960] == (7, 4, b"0100") and sub[36864] == (7, 4, b"0232")
    if name.endswith(".jpg"):
        assert sub[37121] == (7, 4, b"\x01\x02\x03\x00")
    else:
        assert 37121 not in sub
    assert sub[34855][2][:2] == struct.pack(order + "H", 400)


def test_an_iso_beyond_a_short_is_the_recommended_exposure_index(tmp_path):
    """PhotographicSensitivity is a SHORT: ISO 102400 is written as 65535
    there and in full as RecommendedExposureIndex (LONG), SensitivityType 2."""
    shot = replace(SHOT, iso=102400)
    path = ig.write_image(tmp_path / "a.jpg", rgb(np.uint8), exif=exif_bytes(shot, 0, True))
    order, sub = exif_ifd(path)
    assert sub[34855] == (3, 1, struct.pack(order + "HH", 65535, 0))
    assert sub[34864] == (3, 1, struct.pack(order + "HH", 2, 0))
    assert sub[34866] == (4, 1, struct.pack(order + "I", 102400))
    # At ISO 65535 and below, neither extra tag.
    path = ig.write_image(tmp_path / "b.jpg", rgb(np.uint8), exif=exif_bytes(SHOT, 0, True))
    assert not {34864, 34866} & exif_ifd(path)[1].keys()


def test_exif_without_its_app1_prefix_is_accepted(tmp_path):
    bare = exif_bytes(SHOT, 0, True).removeprefix(b"Exif\0\0")
    for name in ("a.jpg", "a.png", "a.tif"):
        path = ig.write_image(tmp_path / name, rgb(np.uint8), exif=bare)
        with Image.open(path) as im:
            assert im.getexif()[271] == "Canon"


@pytest.mark.parametrize("quality", [30, 95])
def test_jpeg_quality_trades_size_for_fidelity(tmp_path, quality):
    smooth = np.stack(np.mgrid[0:64, 0:96] / 192.0, -1).sum(-1, keepdims=True)
    img = (np.concatenate([smooth, 1 - smooth, smooth / 2], -1) * 200).astype(np.uint8)
    path = ig.write_image(tmp_path / "a.jpg", img, color="adobe_rgb", quality=quality)
    with Image.open(path) as im:
        back = np.asarray(im).astype(float)
        assert description(im.info["icc_profile"]) == "Adobe RGB (1998), gamma22 curve (imgform-rs)"
    err = np.sqrt(np.mean((back - img) ** 2))
    assert err < (4 if quality == 30 else 1.5)
    if quality == 95:
        low = ig.write_image(tmp_path / "low.jpg", img, quality=30)
        assert low.stat().st_size < path.stat().st_size


def test_each_profile_describes_its_space():
    titles = {s.name: s.title for s in COLOR_SPACES.values()}
    for color, space in COLOR_SPACES.items():
        icc = icc_profile(color, space.tone)
        if color == "xyz":
            assert icc is None
            continue
        profile = ImageCms.ImageCmsProfile(io.BytesIO(icc))
        assert description(icc).startswith(titles[color])
        # The red colorant (XYZ, D50-adapted) has the chromaticity of the
        # space's red primary, adapted to D50 where the white is not D50.
        assert profile.profile.red_colorant is not None
    assert icc_profile("camera", "srgb") is None


def test_a_profile_is_the_same_bytes_whenever_it_is_made():
    import hashlib
    import time

    first = icc_profile("display_p3", "srgb")
    icc_profile.cache_clear()
    time.sleep(1.1)  # LittleCMS stamps the second a profile is made
    again = icc_profile("display_p3", "srgb")
    assert again == first
    assert first[24:36] == bytes.fromhex("07ea00010001000000000000")  # 2026-01-01 00:00:00
    # The profile ID is the MD5 of the profile with flags, intent and ID zeroed.
    blank = bytearray(first)
    blank[44:48], blank[64:68], blank[84:100] = bytes(4), bytes(4), bytes(16)
    assert hashlib.md5(blank).digest() == first[84:100]


@pytest.mark.parametrize(
    ("name", "dtype"), [("g.png", np.uint16), ("g.jpg", np.uint8), ("g.tif", np.uint16)]
)
def test_a_grey_image_gets_a_grey_profile_that_keeps_its_curve(tmp_path, name, dtype):
    """An RGB profile on a grey image is dropped by libpng and cannot be
    applied by LittleCMS; a grey one converts linear 0.5 to sRGB's code for it."""
    colour = pytest.importorskip("colour")
    half = np.iinfo(dtype).max // 2 + 1
    path = ig.write_image(tmp_path / name, np.full((8, 8), half, dtype), tone="linear")
    if path.suffix == ".tif":
        with tifffile.TiffFile(path) as tif:
            icc = tif.pages[0].tags["InterColorProfile"].value
    else:
        with Image.open(path) as im:
            icc = im.info["icc_profile"]
    profile = ImageCms.ImageCmsProfile(io.BytesIO(icc))
    assert profile.profile.xcolor_space.strip() == "GRAY"
    assert description(icc) == "sRGB grey, linear (imgform-rs)"
    np.testing.assert_allclose(
        profile.profile.media_white_point[0], (0.9642, 1.0, 0.8249), atol=1e-4
    )
    mode = "L" if dtype == np.uint8 else "I;16"
    to_srgb = ImageCms.buildTransform(profile, ImageCms.createProfile("sRGB"), mode, "RGB")
    shown = np.asarray(to_srgb.apply(Image.fromarray(np.full((2, 2), half, dtype))))
    expected = 255 * colour.cctf_encoding(half / np.iinfo(dtype).max, "sRGB")  # 187.5 or 187.8
    # LittleCMS works in 16 bits, so allow the last 8-bit code either way.
    assert np.all(np.abs(shown - expected) <= 1)


def test_profiles_convert_between_spaces_as_the_matrices_do(tmp_path):
    """Pillow converts our Adobe RGB file to sRGB through the embedded profile;
    for colours inside sRGB that is the developed sRGB picture."""
    path = tmp_path / "card.dng"
    scene = np.clip(np.random.default_rng(1).random((48, 64, 3)) * 0.5 + 0.2, 0, 1)
    cfa = ig.simulate_sensor(scene.astype(np.float32), "RGGB", full_well=1e7, read_noise=0)
    write_dng(path, cfa, "RGGB", white_level=4095, black_level=0)
    opts = dict(demosaic="bilinear", bps=8)
    adobe = ig.develop(path, color="adobe_rgb", **opts)
    srgb = ig.develop(path, color="srgb", **opts)
    out = ig.write_image(tmp_path / "adobe.png", adobe, color="adobe_rgb")
    with Image.open(out) as im:
        src = ImageCms.ImageCmsProfile(io.BytesIO(im.info["icc_profile"]))
        converted = ImageCms.profileToProfile(im, src, ImageCms.createProfile("sRGB"))
    diff = np.asarray(converted).astype(float) - srgb
    assert np.sqrt(np.mean(diff**2)) < 1.5


@pytest.mark.parametrize("flip", range(8))
def test_exif_orientation_turns_sensor_pixels_as_develop_does(flip):
    img = rgb(np.uint8, 4, 6, seed=flip)
    exif = Image.Exif()
    exif.load(exif_bytes(SHOT, flip, oriented=False))
    pil = Image.fromarray(img)
    pil.getexif()[274] = exif[274]
    np.testing.assert_array_equal(np.asarray(ImageOps.exif_transpose(pil)), _orient(img, flip))


@pytest.mark.parametrize("stem", ["a" * 240, "写真" * 40, "é" * 125])
@pytest.mark.parametrize("suffix", [".png", ".jpg", ".tif"])
def test_any_name_the_file_system_takes_is_written(tmp_path, stem, suffix):
    from imgform_rs._imagefile import NAME_MAX, partial_path, partial_stem

    img = rgb(np.uint8, 4, 6)
    target = tmp_path / (stem + suffix)
    assert len(os.fsencode(target.name)) <= NAME_MAX
    # Its partial name, 40 bytes longer, used to be refused as too long.
    assert ig.write_image(target, img) == target
    assert os.listdir(tmp_path) == [target.name]
    partial = partial_path(target).name
    assert len(partial.encode("utf-8")) <= NAME_MAX and partial.endswith(suffix)
    # A suffix that leaves no room for the stem: the cut looped for ever.
    assert partial_stem(tmp_path / ("x" * 20 + "." + "y" * 230)).startswith("~")
    # Cut stems stay apart: the batch finds a target's partial files by them.
    twins = (tmp_path / f"{stem[:-1]}{end}{suffix}" for end in "xy")
    assert len({partial_stem(t) for t in twins}) == 2


@pytest.mark.parametrize("flip", range(8))
def test_a_16_bit_colour_png_comes_upright_as_an_8_bit_one_does(tmp_path, flip):
    img = rgb(np.uint8, 6, 8, seed=flip)
    exif = exif_bytes(SHOT, flip, oriented=False)
    eight = ig.write_image(tmp_path / "eight.png", img, exif=exif)
    sixteen = ig.write_image(tmp_path / "sixteen.png", img.astype(np.uint16) * 257, exif=exif)
    # The 16-bit reader (read_png16) used to skip the EXIF turn that the rest get.
    np.testing.assert_array_equal(read_image(sixteen), read_image(eight).astype(np.uint16) * 257)
    assert read_image(eight).shape == _orient(img, flip).shape


@pytest.mark.skipif(RAW_DIR is None, reason="../shared/data/raw is not present")
def test_shot_info_comes_from_the_raw_and_unknowns_stay_out():
    crw = ig.load_raw(RAW_DIR / "canon_powershot_s40_CRW_0113.CRW").shot
    assert crw.iso == 50 and crw.focal_length == pytest.approx(7.09, abs=0.01)
    assert crw.taken == dt.datetime(2021, 3, 26, 21, 14, 52)
    # Magic Lantern leaves APEX zeros, which LibRaw turns into 1 s at f/1.
    ml = ig.load_raw(RAW_DIR / "canon_eos_kiss_x4_magiclantern_colorchart.dng").shot
    assert (ml.make, ml.model) == ("Canon", "Canon EOS Kiss X4")
    assert ml.exposure_time == 0 and ml.f_number == 0 and ml.taken is None
    exif = Image.Exif()
    exif.load(exif_bytes(ml, 0, True))
    assert 33434 not in exif.get_ifd(0x8769) and 306 not in exif


def test_develop_file_writes_profile_and_exif(tmp_path):
    path = tmp_path / "a.dng"
    cfa = (np.arange(40 * 56) % 3000 + 100).astype(np.uint16).reshape(40, 56)
    write_dng(path, cfa, "RGGB", white_level=4095, black_level=64)
    out = ig.develop_file(path, tmp_path / "a.jpg", color="rec2020", quality=90)
    with Image.open(out) as im:
        assert description(im.info["icc_profile"]) == "Rec. 2020, bt709 curve (imgform-rs)"
        assert im.getexif()[274] == 1 and im.getexif()[305] == "imgform-rs"
    with pytest.raises(FileExistsError):
        ig.develop_file(path, out)
    with pytest.raises(ValueError, match="JPEG files take bps 8, got bps=16"):
        ig.develop_file(path, tmp_path / "b.jpg", bps=16)
    with pytest.raises(ValueError, match="PNG files take bps 8 or 16"):
        ig.develop_file(path, tmp_path / "b.png", bps="float")


@pytest.mark.parametrize(
    ("name", "image", "kwargs", "exc", "match"),
    [
        ("a.bmp", rgb(np.uint8), {}, ValueError, r"\.jpg, \.jpeg, \.png"),
        ("a.jpg", rgb(np.uint16), {}, ValueError, "JPEG takes uint8"),
        ("a.png", rgb(np.float32), {}, ValueError, "PNG takes uint8, uint16"),
        ("a.tif", rgb(np.uint8)[..., :2], {}, ValueError, r"\(H, W, 3\)"),
        ("a.jpg", rgb(np.uint8), {"quality": 0}, ValueError, "quality must be an int from 1"),
        ("a.jpg", rgb(np.uint8), {"quality": True}, ValueError, "quality must be an int"),
        ("a.png", rgb(np.uint8), {"color": "cmyk"}, ValueError, "color must be one of"),
        ("a.png", rgb(np.uint8), {"tone": "gamma"}, ValueError, "tone must be one of"),
        ("a.png", rgb(np.uint8), {"exif": "Exif"}, TypeError, "exif must be bytes"),
        ("a.jpg", rgb(np.uint8), {"exif": b"Exif\0\0garbage"}, ValueError, "exif must be EXIF"),
    ],
)
def test_write_image_refuses_what_it_cannot_write(tmp_path, name, image, kwargs, exc, match):
    with pytest.raises(exc, match=match):
        ig.write_image(tmp_path / name, image, **kwargs)
    assert not (tmp_path / name).exists()


BIG_EXIF = Image.Exif()
BIG_EXIF[270] = "x" * 70000  # ImageDescription: over one JPEG segment


@pytest.mark.parametrize(
    ("name", "image", "kwargs", "match"),
    [
        ("a.jpg", rgb(np.uint8, 0, 8), {}, r"at least one pixel, got shape \(0, 8, 3\)"),
        ("a.png", rgb(np.uint16, 8, 0), {}, "at least one pixel"),
        ("a.tif", rgb(np.uint16, 0, 5), {}, "at least one pixel"),
        ("a.jpg", rgb(np.uint8, 1, 65501), {}, "at most 65500 pixels a side, got 65501 x 1"),
        ("a.jpg", rgb(np.uint8), {"exif": BIG_EXIF.tobytes()}, "at most 65533 bytes of EXIF"),
    ],
)
def test_what_an_encoder_would_refuse_halfway_is_refused_before_the_file(
    tmp_path, name, image, kwargs, match
):
    """These failed inside the encoder, after it had emptied the target."""
    target = ig.write_image(tmp_path / name, rgb(image.dtype.type))
    kept = target.read_bytes()
    with pytest.raises(ValueError, match=match):
        ig.write_image(target, image, overwrite=True, **kwargs)
    assert target.read_bytes() == kept and os.listdir(tmp_path) == [name]


@pytest.mark.parametrize("existing", [False, True])
def test_a_write_that_fails_halfway_leaves_no_partial_file_and_the_old_one_whole(
    tmp_path, monkeypatch, existing
):
    target = tmp_path / "a.tif"
    if existing:
        ig.write_image(target, rgb(np.uint16))
        kept = target.read_bytes()

    def disk_full(path, *args, **kwargs):
        with open(path, "wb") as file:
            file.write(b"II*\0")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(tifffile, "imwrite", disk_full)
    with pytest.raises(OSError, match="No space left"):
        ig.write_image(target, rgb(np.uint16, seed=1), overwrite=True)
    assert os.listdir(tmp_path) == (["a.tif"] if existing else [])
    if existing:
        assert target.read_bytes() == kept


def test_a_written_file_gets_the_permissions_of_any_new_file(tmp_path):
    """The temporary file becomes the output: it must not keep a temporary
    file's private 0600 mode."""
    umask = os.umask(0o022)
    os.umask(umask)
    path = ig.write_image(tmp_path / "a.png", rgb(np.uint8))
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


@pytest.mark.skipif(RAW_DIR is None, reason="../shared/data/raw is not present")
def test_a_real_raw_keeps_its_shot_details_in_every_format(tmp_path):
    source = RAW_DIR / "canon_powershot_s40_CRW_0113.CRW"
    raw = ig.load_raw(source)
    for name, bps in [("s40.jpg", 8), ("s40.png", 16), ("s40.tif", "float"), ("s40.exr", "float")]:
        tone = "linear" if bps == "float" else "auto"
        out = ig.develop_file(raw, tmp_path / name, bps=bps, tone=tone, demosaic="bilinear")
        if out.suffix == ".exr":
            openexr = pytest.importorskip("OpenEXR")
            with openexr.File(str(out)) as exr:
                header = dict(exr.header())
            assert header["capDate"] == "2021:03:26 21:14:52" and header["isoSpeed"] == 50
            assert header["aperture"] == pytest.approx(2.8, abs=0.01)
            assert header["expTime"] == pytest.approx(0.2013, abs=1e-4)
            assert header["cameraMake"] == "Canon"  # from the CRW's CIFF record
            continue
        if out.suffix == ".tif":
            with tifffile.TiffFile(out) as tif:
                tags = {t.name: t.value for t in tif.pages[0].tags.values()}
                assert tif.pages[0].dtype == np.float32
            assert tags["DateTime"] == "2021:03:26 21:14:52"
            assert description(tags["InterColorProfile"]) == "sRGB, linear (imgform-rs)"
            continue
        with Image.open(out) as im:
            sub = im.getexif().get_ifd(0x8769)
            assert sub[36867] == "2021:03:26 21:14:52" and sub[34855] == 50
            assert float(sub[33437]) == pytest.approx(2.8, abs=0.01)
            assert description(im.info["icc_profile"]) == "sRGB, srgb curve (imgform-rs)"


# --- EXR ----------------------------------------------------------------------

# The chromaticities each space must carry: (red, green, blue, white) x, y as
# the specifications give them; XYZ by OpenEXR's convention (identity matrix).
EXR_CHROMATICITIES = {
    "srgb": (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290),
    "prophoto": (0.7347, 0.2653, 0.1596, 0.8404, 0.0366, 0.0001, 0.3457, 0.3585),
    "aces2065_1": (0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.0770, 0.32168, 0.33767),
    "xyz": (1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1 / 3, 1 / 3),
}


@pytest.mark.parametrize("color", [*EXR_CHROMATICITIES, "camera"])
def test_exr_keeps_linear_floats_with_chromaticities_and_shot_details(tmp_path, color):
    openexr = pytest.importorskip("OpenEXR")
    img = rgb(np.float32) * 4 - 1  # EXR keeps values outside [0, 1]
    exif = exif_bytes(SHOT, 0, True)
    path = ig.write_image(tmp_path / "a.exr", img, color=color, tone="linear", exif=exif)
    with openexr.File(str(path)) as exr:
        header, back = dict(exr.header()), exr.channels()["RGB"].pixels.copy()
    np.testing.assert_array_equal(back, img)
    if color == "camera":
        assert "chromaticities" not in header
    else:
        np.testing.assert_allclose(header["chromaticities"], EXR_CHROMATICITIES[color], atol=1e-7)
    assert header["cameraMake"] == "Canon" and header["cameraModel"] == "Canon EOS Kiss X4"
    assert header["lensModel"] == SHOT.lens and header["owner"] == SHOT.artist
    assert header["capDate"] == "2026:11:27 10:30:05"
    assert header["expTime"] == pytest.approx(1 / 125) and header["aperture"] == pytest.approx(5.6)
    assert header["isoSpeed"] == 400 and header["focalLength"] == 35


def test_exr_text_beyond_ascii_is_the_exif_s_utf8(tmp_path):
    openexr = pytest.importorskip("OpenEXR")
    shot = replace(SHOT, artist="José Müller", lens="Objectif ƒ/1.8")
    exif = exif_bytes(shot, 0, True)
    path = ig.write_image(tmp_path / "a.exr", rgb(np.float32), tone="linear", exif=exif)
    with openexr.File(str(path)) as exr:
        header = dict(exr.header())
    assert header["owner"] == shot.artist and header["lensModel"] == shot.lens


def test_exr_takes_the_first_set_value_of_a_multi_valued_exif_number(tmp_path):
    openexr = pytest.importorskip("OpenEXR")
    exif = Image.Exif()
    exif.get_ifd(0x8769)[34855] = (0, 200)  # ISOSpeedRatings: count "any" in EXIF 2.2
    path = ig.write_image(tmp_path / "a.exr", rgb(np.float32), tone="linear", exif=exif.tobytes())
    with openexr.File(str(path)) as exr:
        assert dict(exr.header())["isoSpeed"] == 200


def test_a_grey_exr_has_one_luminance_channel(tmp_path):
    openexr = pytest.importorskip("OpenEXR")
    grey = rgb(np.float32)[..., 0]
    path = ig.write_image(tmp_path / "g.exr", grey, tone="linear")
    with openexr.File(str(path)) as exr:
        channels = {k: c.pixels.copy() for k, c in exr.channels().items()}
    assert list(channels) == ["Y"]
    np.testing.assert_array_equal(channels["Y"], grey)


@pytest.mark.parametrize(
    ("image", "kwargs", "exc", "match"),
    [
        (rgb(np.float32), {}, ValueError, "EXR files hold linear light.*'srgb' curve"),
        (rgb(np.float32), {"color": "adobe_rgb"}, ValueError, "'gamma22' curve"),
        (rgb(np.uint16), {"tone": "linear"}, ValueError, "EXR takes float32"),
        (
            rgb(np.float32),
            {"tone": "linear", "exif": exif_bytes(SHOT, 5, oriented=False)},
            ValueError,
            "EXR files have no orientation.*orientation 8",
        ),
    ],
)
def test_exr_refuses_what_its_readers_would_misread(tmp_path, image, kwargs, exc, match):
    pytest.importorskip("OpenEXR")
    with pytest.raises(exc, match=match):
        ig.write_image(tmp_path / "a.exr", image, **kwargs)
    assert not (tmp_path / "a.exr").exists()


def test_exr_without_openexr_says_how_to_install_it(tmp_path, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "OpenEXR", None)
    with pytest.raises(ImportError, match=r"pip install imgform-rs\[exr\]"):
        ig.write_image(tmp_path / "a.exr", rgb(np.float32), tone="linear")


def test_exr_write_errors_are_os_errors(tmp_path):
    pytest.importorskip("OpenEXR")
    with pytest.raises(OSError, match="missing"):
        ig.write_image(tmp_path / "missing" / "a.exr", rgb(np.float32), tone="linear")


def test_develop_file_writes_linear_exr_and_checks_options_first(tmp_path):
    openexr = pytest.importorskip("OpenEXR")
    path = tmp_path / "a.dng"
    cfa = (np.arange(40 * 56) % 3000 + 100).astype(np.uint16).reshape(40, 56)
    write_dng(path, cfa, "RGGB", white_level=4095, black_level=64, orientation=6)
    opts = dict(bps="float", tone="linear", demosaic="bilinear", color="rec2020")
    out = ig.develop_file(path, tmp_path / "a.exr", **opts)
    with openexr.File(str(out)) as exr:
        back, header = exr.channels()["RGB"].pixels.copy(), dict(exr.header())
    np.testing.assert_array_equal(back, ig.develop(path, **opts))
    np.testing.assert_allclose(header["chromaticities"][:2], (0.708, 0.292), atol=1e-7)
    assert header["cameraMake"] == "imgform-rs"
    with pytest.raises(ValueError, match='EXR files take bps "float", got bps=16'):
        ig.develop_file(path, tmp_path / "b.exr", bps=16)
    with pytest.raises(ValueError, match="linear light"):
        ig.develop_file(path, tmp_path / "b.exr", bps="float")
    with pytest.raises(ValueError, match="no orientation"):
        ig.develop_file(path, tmp_path / "b.exr", orientation="none", **opts)
    assert not (tmp_path / "b.exr").exists()


def test_cli_writes_exr_only_for_linear_float(tmp_path, capsys):
    openexr = pytest.importorskip("OpenEXR")
    from imgform_rs.cli import main

    path = tmp_path / "a.dng"
    cfa = (np.arange(40 * 56) % 3000 + 100).astype(np.uint16).reshape(40, 56)
    write_dng(path, cfa, "RGGB", white_level=4095)
    out = tmp_path / "out"
    assert main(["develop", str(path), "-o", str(out), "--format", "exr"]) == 2
    assert 'EXR files take bps "float"' in capsys.readouterr().err
    assert main(["develop", str(path), "-o", str(out), "--format", "exr", "--bps", "float"]) == 2
    assert "EXR files hold linear light" in capsys.readouterr().err
    assert not out.exists()
    argv = ["develop", str(path), "-o", str(out), "--format", "exr", "--bps", "float"]
    assert main([*argv, "--tone", "linear", "--color", "aces2065_1"]) == 0
    with openexr.File(str(out / "a.exr")) as exr:
        white = dict(exr.header())["chromaticities"][6:]
    np.testing.assert_allclose(white, (0.32168, 0.33767), atol=1e-7)


def test_tiff_keeps_the_exif_in_ifd0_for_the_reason_the_module_gives(tmp_path):
    """_imagefile's docstring: tifffile drops the EXIF sub-IFD's pointer from
    extratags. If tifffile ever writes it, this fails: move the EXIF there."""
    path = ig.write_image(tmp_path / "a.tif", rgb(np.uint16), exif=exif_bytes(SHOT, 0, True))
    with tifffile.TiffFile(path) as tif:
        tags = tif.pages[0].tags
        assert "ExifTag" not in tags and tags["Make"].value == "Canon"
    assert 34665 in tifffile.TIFF.TAG_FILTERED


def test_a_replaced_file_keeps_its_permissions_and_a_link_stays_a_link(tmp_path):
    real = ig.write_image(tmp_path / "real.png", rgb(np.uint8))
    real.chmod(0o640)
    link = tmp_path / "link.png"
    link.symlink_to(real.name)
    new = rgb(np.uint8, seed=1)
    assert ig.write_image(link, new, overwrite=True) == link
    assert link.is_symlink() and os.readlink(link) == "real.png"
    assert real.stat().st_mode & 0o777 == 0o640
    with Image.open(real) as im:
        np.testing.assert_array_equal(np.asarray(im), new)
    assert sorted(os.listdir(tmp_path)) == ["link.png", "real.png"]


def test_a_folder_or_a_loop_of_links_is_refused_naming_the_target(tmp_path, monkeypatch):
    """A folder was found only after the whole image was encoded, and the
    error named the hidden partial file; a loop of links was a RuntimeError."""
    import imgform_rs._imagefile as imagefile

    (tmp_path / "dir.png").mkdir()
    (tmp_path / "loop.png").symlink_to("loop.png")
    encoded = []
    monkeypatch.setattr(imagefile, "_pillow", lambda *a: encoded.append(a))
    with pytest.raises(IsADirectoryError, match=r"dir\.png'$"):
        ig.write_image(tmp_path / "dir.png", rgb(np.uint8), overwrite=True)
    with pytest.raises(OSError, match=r"symbolic links: '.*loop\.png'$"):
        ig.write_image(tmp_path / "loop.png", rgb(np.uint8), overwrite=True)
    assert encoded == [] and sorted(os.listdir(tmp_path)) == ["dir.png", "loop.png"]
