//! Tests of the shared skeleton and of each method against a direct,
//! per-pixel oracle with mirror indexing everywhere.

use super::*;

fn pattern(name: &str) -> CfaPattern {
    CfaPattern::from_name(name).unwrap()
}

/// A deterministic, textured mosaic in 0..=1000.
fn texture(w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .map(|i| ((i * 7919 + (i / w) * 104_729) % 1001) as f32)
        .collect()
}

fn run<T: Sample>(raw: &[T], w: usize, h: usize, name: &str, method: Method) -> Vec<T> {
    let view = ImageView::contiguous(raw, w, h, 1).unwrap();
    let mut out = vec![T::default(); 3 * w * h];
    demosaic(view, &pattern(name), method, None, &mut out).unwrap();
    out
}

/// The Malvar and bilinear 5x5 kernels (eighths), indexed by the site kind:
/// 0 green at chroma, 1 chroma along the row at green, 2 chroma along the
/// column at green, 3 other chroma at chroma.
fn kernel(method: Method, kind: usize) -> [[f32; 5]; 5] {
    let t = |k: [[f32; 5]; 5]| {
        let mut o = [[0.0; 5]; 5];
        for i in 0..5 {
            for j in 0..5 {
                o[i][j] = k[j][i];
            }
        }
        o
    };
    let z = 0.0;
    let (g, row, other) = match method {
        Method::Bilinear => (
            [
                [z, z, z, z, z],
                [z, z, 2., z, z],
                [z, 2., z, 2., z],
                [z, z, 2., z, z],
                [z; 5],
            ],
            [[z; 5], [z; 5], [z, 4., z, 4., z], [z; 5], [z; 5]],
            [
                [z, z, z, z, z],
                [z, 2., z, 2., z],
                [z; 5],
                [z, 2., z, 2., z],
                [z; 5],
            ],
        ),
        _ => (
            [
                [z, z, -1., z, z],
                [z, z, 2., z, z],
                [-1., 2., 4., 2., -1.],
                [z, z, 2., z, z],
                [z, z, -1., z, z],
            ],
            [
                [z, z, 0.5, z, z],
                [z, -1., z, -1., z],
                [-1., 4., 5., 4., -1.],
                [z, -1., z, -1., z],
                [z, z, 0.5, z, z],
            ],
            [
                [z, z, -1.5, z, z],
                [z, 2., z, 2., z],
                [-1.5, z, 6., z, -1.5],
                [z, 2., z, 2., z],
                [z, z, -1.5, z, z],
            ],
        ),
    };
    [g, row, t(row), other][kind]
}

/// Direct convolution with mirrored indices: the oracle for the linear
/// methods.
fn linear_oracle(raw: &[f32], w: usize, h: usize, p: &CfaPattern, method: Method) -> Vec<f32> {
    let mut out = vec![0.0; 3 * w * h];
    for y in 0..h {
        for x in 0..w {
            let own = usize::from(p.color_at(y, x));
            let conv = |kind: usize| {
                let k = kernel(method, kind);
                let mut s = 0.0f64;
                for (i, kr) in k.iter().enumerate() {
                    for (j, &kv) in kr.iter().enumerate() {
                        let yy = mirror(y as isize + i as isize - 2, h);
                        let xx = mirror(x as isize + j as isize - 2, w);
                        s += f64::from(kv) * f64::from(raw[yy * w + xx]);
                    }
                }
                (s / 8.0) as f32
            };
            for c in 0..3 {
                out[3 * (y * w + x) + c] = if c == own {
                    raw[y * w + x]
                } else if own == 1 {
                    // Chroma at a green site: is colour c on this row?
                    let along_row = usize::from(p.color_at(y, x + 1)) == c;
                    conv(if along_row { 1 } else { 2 })
                } else if c == 1 {
                    conv(0)
                } else {
                    conv(3)
                };
            }
        }
    }
    out
}

#[test]
fn linear_methods_match_the_mirrored_convolution_oracle_for_every_phase_and_size() {
    for method in [Method::Bilinear, Method::Malvar2004] {
        for name in crate::cfa::BAYER_NAMES {
            for (w, h) in [(2, 2), (3, 2), (2, 5), (7, 5), (9, 131), (16, 70)] {
                let raw = texture(w, h);
                let got = run(&raw, w, h, name, method);
                let want = linear_oracle(&raw, w, h, &pattern(name), method);
                for (i, (a, b)) in got.iter().zip(&want).enumerate() {
                    assert!(
                        (a - b).abs() <= 1e-3,
                        "{method:?} {name} {w}x{h} sample {i}: {a} vs {b}"
                    );
                }
            }
        }
    }
}

#[test]
fn one_hand_computed_pixel_per_linear_method() {
    // 5x5 RGGB mosaic, value = 10 * y + x. Pixel (2, 2) is red.
    let raw: Vec<f32> = (0..25).map(|i| (10 * (i / 5) + i % 5) as f32).collect();
    let bil = run(&raw, 5, 5, "RGGB", Method::Bilinear);
    let px = &bil[3 * 12..3 * 13];
    // G = (21 + 23 + 12 + 32) / 4 = 22; B = (11 + 13 + 31 + 33) / 4 = 22.
    assert_eq!(px, &[22.0, 22.0, 22.0]);
    let mal = run(&raw, 5, 5, "RGGB", Method::Malvar2004);
    // On a linear ramp the Laplacian terms vanish: the same 22s.
    assert_eq!(&mal[3 * 12..3 * 13], &[22.0, 22.0, 22.0]);
}

#[test]
fn every_method_keeps_samples_and_constants_for_every_dtype() {
    for method in Method::ALL {
        for name in crate::cfa::BAYER_NAMES {
            for (w, h) in [(2, 2), (5, 3), (33, 70)] {
                let tex: Vec<u16> = texture(w, h).iter().map(|&v| v as u16 * 60).collect();
                let out = run(&tex, w, h, name, method);
                let p = pattern(name);
                for y in 0..h {
                    for x in 0..w {
                        let c = usize::from(p.color_at(y, x));
                        assert_eq!(out[3 * (y * w + x) + c], tex[y * w + x], "{method:?}");
                    }
                }
                let flat = vec![200u8; w * h];
                assert!(run(&flat, w, h, name, method).iter().all(|&v| v == 200));
            }
        }
    }
}

#[test]
fn integer_outputs_are_clamped_not_wrapped() {
    // A bright red dot on black makes Malvar overshoot below zero nearby.
    let mut raw = vec![0u8; 36];
    raw[2 * 6 + 2] = 255;
    let out = run(&raw, 6, 6, "RGGB", Method::Malvar2004);
    let f: Vec<f32> = raw.iter().map(|&v| f32::from(v)).collect();
    let fo = run(&f, 6, 6, "RGGB", Method::Malvar2004);
    assert!(fo.iter().any(|&v| v < 0.0));
    for (o, v) in out.iter().zip(&fo) {
        assert_eq!(*o, v.clamp(0.0, 255.0).round() as u8);
    }
}

#[test]
fn non_finite_floats_are_refused_by_every_method() {
    let mut raw = vec![0.5f32; 36];
    raw[4 * 6 + 1] = f32::INFINITY;
    for method in Method::ALL {
        let name = if method.supports(&pattern("RGGB")) {
            "RGGB"
        } else {
            "XTRANS"
        };
        let view = ImageView::contiguous(&raw, 6, 6, 1).unwrap();
        let err = demosaic(view, &pattern(name), method, None, &mut [0.0; 108]).unwrap_err();
        assert!(err.to_string().contains("inf at row 4, column 1"), "{err}");
    }
}

#[test]
fn bands_do_not_change_the_result() {
    // More rows than one band, compared with the oracle at band seams.
    let (w, h) = (5, 3 * ROWS_PER_BAND + 3);
    let raw = texture(w, h);
    let got = run(&raw, w, h, "GBRG", Method::Malvar2004);
    let want = linear_oracle(&raw, w, h, &pattern("GBRG"), Method::Malvar2004);
    assert!(got.iter().zip(&want).all(|(a, b)| (a - b).abs() <= 1e-3));
}

#[test]
fn hamilton_adams_follows_an_edge() {
    // Vertical edge: columns 0..3 dark, 3.. bright. Green at a chroma site
    // next to the edge must come from its own column, not across it.
    let (w, h) = (8, 8);
    let raw: Vec<f32> = (0..w * h)
        .map(|i| if i % w < 3 { 10.0 } else { 200.0 })
        .collect();
    let ha = run(&raw, w, h, "RGGB", Method::HamiltonAdams);
    let bil = run(&raw, w, h, "RGGB", Method::Bilinear);
    // (2, 2) is red, column 2 is dark: HA keeps it dark, bilinear blurs it.
    assert_eq!(ha[3 * (2 * w + 2) + 1], 10.0);
    assert!(bil[3 * (2 * w + 2) + 1] > 50.0);
}

#[test]
fn nearest_copies_the_cell() {
    let raw: Vec<u8> = vec![1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12];
    // 4x3 GRBG: row 0 G R G R, row 1 B G B G, row 2 G R G R.
    let out = run(&raw, 4, 3, "GRBG", Method::Nearest);
    assert_eq!(&out[..6], &[2, 1, 5, 2, 1, 5]);
    assert_eq!(&out[12..18], &[2, 6, 5, 2, 6, 5]);
    // Row 2's cell borrows row 1 by mirroring.
    assert_eq!(&out[24..30], &[10, 9, 5, 10, 9, 5]);
}

#[test]
fn bad_input_is_refused_with_a_reason() {
    let raw = [0u8; 4];
    let mut out = [0u8; 12];
    let view = ImageView::contiguous(&raw, 4, 1, 1).unwrap();
    let err = demosaic(
        view,
        &pattern("RGGB"),
        Method::Bilinear,
        None,
        &mut [0u8; 12],
    )
    .unwrap_err();
    assert!(err.to_string().contains("at least 2x2"), "{err}");
    let view = ImageView::contiguous(&raw, 2, 2, 1).unwrap();
    let err = demosaic(view, &CfaPattern::xtrans(), Method::Nearest, None, &mut out).unwrap_err();
    assert!(err.to_string().contains("X-Trans"), "{err}");
    let err = demosaic(
        view,
        &pattern("RGGB"),
        Method::Nearest,
        None,
        &mut out[..11],
    )
    .unwrap_err();
    assert!(err.to_string().contains("expected 12"), "{err}");
    let err = Method::from_name("vng").unwrap_err().to_string();
    assert!(
        err.contains("\"vng\"") && err.contains("hamilton_adams"),
        "{err}"
    );
}

#[test]
fn every_instruction_set_gives_the_same_bits() {
    let (w, h) = (37, 2 * ROWS_PER_BAND + 5);
    let raw: Vec<u16> = texture(w, h).iter().map(|&v| v as u16 * 65).collect();
    let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
    let phase = Phase { ry: 1, rx: 0 };
    // Nearest only copies samples: one instruction set is all it has.
    for method in Method::ALL.into_iter().filter(|&m| m != Method::Nearest) {
        let run_with = |isa| {
            let mut out = vec![0u16; 3 * w * h];
            run_method(&view, phase, method, 65535.0, isa, &Convert, &mut out);
            out
        };
        let base = run_with(Isa::Baseline);
        for isa in Isa::available() {
            assert_eq!(base, run_with(isa), "{method:?} {isa:?}");
        }
    }
}

#[test]
fn the_any_pattern_interpolation_is_bilinear_on_bayer() {
    let (w, h) = (13, 10);
    let raw = texture(w, h);
    let view = ImageView::contiguous(&raw, w, h, 1).unwrap();
    let p = pattern("GBRG");
    let mut any = vec![0.0f32; 3 * w * h];
    xtrans::run(&view, &p, &mut any);
    let bil = run(&raw, w, h, "GBRG", Method::Bilinear);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            for c in 0..3 {
                let i = 3 * (y * w + x) + c;
                assert!((any[i] - bil[i]).abs() <= 1e-3, "({y}, {x}, {c})");
            }
        }
    }
}

#[test]
fn xtrans_needs_a_whole_tile_and_keeps_its_samples() {
    let raw = texture(5, 8);
    let view = ImageView::contiguous(&raw, 5, 8, 1).unwrap();
    let mut out = vec![0.0f32; 3 * 40];
    let err = demosaic(
        view,
        &CfaPattern::xtrans(),
        Method::Bilinear,
        None,
        &mut out,
    )
    .unwrap_err();
    assert!(err.to_string().contains("6x6"), "{err}");
    let (w, h) = (9, 7);
    let raw = texture(w, h);
    let out = run(&raw, w, h, "XTRANS", Method::Bilinear);
    let p = CfaPattern::xtrans();
    for y in 0..h {
        for x in 0..w {
            assert_eq!(
                out[3 * (y * w + x) + p.color_at(y, x) as usize],
                raw[y * w + x]
            );
        }
    }
}

/// The halo is a true bound on the reach: a change one pixel beyond it (a
/// value inside the mosaic's range, so clamping methods clamp alike) leaves
/// the centre pixel unchanged, in the image interior and at a corner.
#[test]
fn no_output_reaches_beyond_its_methods_halo() {
    let cases = [("GRBG", &Method::ALL[..]), ("XTRANS", &Method::XTRANS[..])];
    // Room for a change beyond the widest halo on both sides of the centre.
    let widest = cases
        .iter()
        .flat_map(|(name, methods)| methods.iter().map(|m| m.halo(&pattern(name))))
        .max()
        .unwrap_or(0);
    let (w, h) = (2 * widest + 8, 2 * widest + 6);
    let raw = texture(w, h);
    for (name, methods) in cases {
        for &method in methods {
            let halo = method.halo(&pattern(name));
            let base = run(&raw, w, h, name, method);
            for (cy, cx) in [(h / 2, w / 2), (0, 0)] {
                for (dy, dx) in [(halo + 1, 0), (0, halo + 1), (halo + 1, halo + 1)] {
                    let mut moved = raw.clone();
                    let i = (cy + dy) * w + cx + dx;
                    moved[i] = 1000.0 - moved[i];
                    let out = run(&moved, w, h, name, method);
                    let c = 3 * (cy * w + cx);
                    assert_eq!(
                        out[c..c + 3],
                        base[c..c + 3],
                        "{name} {method:?} ({dy}, {dx})"
                    );
                }
            }
        }
    }
}

#[test]
fn the_default_white_level_is_the_bit_depth_of_integer_samples() {
    let cases = [
        (0.0, 255.0),
        (255.0, 255.0),
        (256.0, 511.0),
        (1023.0, 1023.0),
        (4095.0, 4095.0),
        (4096.0, 8191.0),
        (16383.0, 16383.0),
        (40000.0, 65535.0),
        (65535.0, 65535.0),
    ];
    for (largest, level) in cases {
        assert_eq!(white_level::<u16>(largest), level, "{largest}");
    }
    assert_eq!(white_level::<u8>(3.0), 255.0);
    assert_eq!(white_level::<f32>(0.7), 1.0);
    assert_eq!(white_level::<f32>(300.0), 300.0);
}

/// A 12-bit mosaic in `u16` is demosaicked at its bit depth by default, and
/// 8-bit samples give the same result in either integer type.
#[test]
fn scaled_methods_take_the_white_level_of_the_data() {
    let (w, h) = (21, 18);
    let eight: Vec<u8> = texture(w, h).iter().map(|&v| (v / 4.0) as u8).collect();
    let wide: Vec<u16> = eight.iter().map(|&v| u16::from(v)).collect();
    let twelve: Vec<u16> = eight.iter().map(|&v| u16::from(v) * 16).collect();
    let given = |raw: &[u16], method, level| {
        let mut out = vec![0u16; 3 * w * h];
        let view = ImageView::contiguous(raw, w, h, 1).unwrap();
        demosaic(view, &pattern("GRBG"), method, level, &mut out).unwrap();
        out
    };
    for method in Method::ALL.into_iter().filter(|m| m.scaled()) {
        let narrow: Vec<u16> = run(&eight, w, h, "GRBG", method)
            .into_iter()
            .map(u16::from)
            .collect();
        assert_eq!(narrow, run(&wide, w, h, "GRBG", method), "{method:?}");
        let inferred = run(&twelve, w, h, "GRBG", method);
        assert_eq!(inferred, given(&twelve, method, Some(4095.0)), "{method:?}");
        assert_ne!(
            inferred,
            given(&twelve, method, Some(65535.0)),
            "{method:?}"
        );
    }
}

#[test]
fn a_white_level_must_be_positive_and_finite() {
    let raw = vec![0.5f32; 16];
    for level in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        let view = ImageView::contiguous(&raw, 4, 4, 1).unwrap();
        let err = demosaic(
            view,
            &pattern("RGGB"),
            Method::Mlri,
            Some(level),
            &mut [0.0; 48],
        );
        let message = err.unwrap_err().to_string();
        assert!(
            message.contains("white_level must be a finite number > 0"),
            "{message}"
        );
    }
}
