//! The network's layers on Intel's AMX tiles ([`crate::cpu::Level::Amx`]).
//!
//! A tile multiply (`tdpbusd`) takes a tile of 16 rows of 64 unsigned
//! bytes and one of 64 signed bytes by 16 outputs: 16 x 16 sums of 64
//! products each, 16 k products an instruction where AVX-512's VNNI takes
//! 32. Each row of the first tile is an output quad's window: its three
//! quads along the input row lie side by side in memory, so row `m` of a
//! block is the same bytes as row `m - 1` moved on by one quad (a tile
//! load with a stride of one quad), and the window's `3 CIN` bytes come in
//! chunks of 64 whose bytes past the window meet zero weights.
//!
//! The codes are 15 bits and the products take 8, so each input row is
//! split into its high and its low bytes, each multiplied by the same
//! weights: the sum is `256 hi + lo`, exact in `i32` as every path's
//! ([`super::TOP`]), so the bits are the other builds' bits.
//!
//! Speed, 24 MP on two threads of a Xeon with AMX: the whole "quality"
//! method at 18.2 MP/s against 12.7 with `IMGFORM_ISA=avx512` (VNNI),
//! interleaved runs; its base alone runs at 46, so the network now takes
//! three fifths of the time where it took three quarters. A block's
//! multiplies are about two thirds of the layers' time, the bytes' split
//! and the requantisation the rest.

use super::{finish, Layer, Out, LANES};

/// Bytes in a tile's row, and rows in a tile.
const ROW: usize = 64;
const ROWS: usize = 16;
/// Output quads a block computes: one per row of a tile.
const BLOCK: usize = ROWS;

/// A layer's weights as the second operands of the tile multiplies: per
/// row of taps, per chunk of 64 bytes of a window row and per 16 outputs,
/// one tile of 16 rows (four inputs each) by 16 outputs, four bytes apart.
pub(in crate::demosaic) struct Tiles {
    bytes: Vec<i8>,
    /// Chunks of 64 bytes that cover a window row's three quads.
    chunks: usize,
    /// Tiles of 16 outputs.
    halves: usize,
}

impl Tiles {
    /// Packs the weights `weight(tap, input, output)` of a layer of `cin`
    /// inputs and `cout` outputs (padded to 16).
    pub(super) fn pack(
        cin: usize,
        cout: usize,
        weight: impl Fn(usize, usize, usize) -> i8,
    ) -> Self {
        let chunks = (3 * cin).div_ceil(ROW);
        let halves = cout.div_ceil(LANES);
        let mut bytes = vec![0i8; 3 * chunks * halves * ROWS * ROW];
        for (t, tile) in bytes.chunks_exact_mut(ROWS * ROW).enumerate() {
            let (dy, chunk, half) = (t / (chunks * halves), t / halves % chunks, t % halves);
            for (k, i) in (chunk * ROW..(chunk + 1) * ROW)
                .take_while(|&k| k < 3 * cin)
                .zip(0..)
            {
                let (dx, input) = (k / cin, k % cin);
                for n in 0..LANES.min(cout - half * LANES) {
                    tile[(i / 4) * ROW + n * 4 + i % 4] =
                        weight(3 * dy + dx, input, half * LANES + n);
                }
            }
        }
        Tiles {
            bytes,
            chunks,
            halves,
        }
    }

    fn tile(&self, dy: usize, chunk: usize, half: usize) -> *const i8 {
        self.bytes[((dy * self.chunks + chunk) * self.halves + half) * ROWS * ROW..].as_ptr()
    }
}

/// The high and the low bytes of a layer's three input rows, with room
/// past the row's end for a block's last tile rows to read.
#[derive(Default)]
pub(in crate::demosaic) struct Planes {
    high: [Vec<u8>; 3],
    low: [Vec<u8>; 3],
}

impl Planes {
    /// Splits `rows` (codes of 15 bits) into their bytes.
    #[inline(always)]
    fn split(&mut self, rows: [&[i16]; 3], cin: usize) {
        // A block's last tile row reads from 15 quads on, up to 128 bytes
        // (two chunks) past it.
        let len = rows[0].len() + (BLOCK + 1) * cin + 2 * ROW;
        for ((high, low), row) in self.high.iter_mut().zip(&mut self.low).zip(rows) {
            high.resize(len, 0);
            low.resize(len, 0);
            for ((h, l), &v) in high.iter_mut().zip(low.iter_mut()).zip(row) {
                // Codes are 0 ..= 32767: the high byte takes 7 bits.
                (*h, *l) = ((v >> 8) as u8, v as u8);
            }
        }
    }
}

/// The tile configuration for the process's threads: palette 1, every one
/// of the eight tiles 16 rows of 64 bytes. Loaded for a row of a layer
/// and released after it, so a thread between rows keeps no tile state
/// for the OS to save.
#[repr(C, align(64))]
struct Config([u8; 64]);

static CONFIG: Config = {
    let mut c = [0u8; 64];
    c[0] = 1;
    let mut t = 0;
    while t < 8 {
        c[16 + 2 * t] = ROW as u8;
        c[48 + t] = ROWS as u8;
        t += 1;
    }
    Config(c)
};

/// Tiles configured on this thread for as long as it lives.
struct Session;

impl Session {
    /// # Safety
    /// The CPU must have AMX and the OS must have granted its state
    /// ([`crate::cpu::has_amx`]).
    unsafe fn start() -> Self {
        // SAFETY: by the caller; the configuration is 64 aligned bytes.
        unsafe {
            std::arch::asm!(
                "ldtilecfg [{}]",
                in(reg) CONFIG.0.as_ptr(),
                out("tmm0") _, out("tmm1") _, out("tmm2") _, out("tmm3") _,
                out("tmm4") _, out("tmm5") _, out("tmm6") _, out("tmm7") _,
                options(nostack, readonly),
            )
        };
        Session
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        // SAFETY: a session exists only where tiles were configured.
        unsafe {
            std::arch::asm!(
                "tilerelease",
                out("tmm0") _, out("tmm1") _, out("tmm2") _, out("tmm3") _,
                out("tmm4") _, out("tmm5") _, out("tmm6") _, out("tmm7") _,
                options(nostack, nomem),
            )
        };
    }
}

/// One row of a layer, as [`super::conv_row`] computes it: output quads
/// `1 .. n - 1` from `rows`, in blocks of 16.
///
/// Compiled for AVX-512, which every CPU with AMX has: the bytes' split,
/// the sums' assembly and their requantisation are a third of the work,
/// and in the baseline's SSE2 they took as long as the tiles.
///
/// # Safety
/// The CPU must have AMX and the OS must have granted its state
/// ([`crate::cpu::has_amx`]), and AVX-512 (F, BW, DQ, VL).
#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma")]
pub(super) unsafe fn conv_row<const CIN: usize>(
    rows: [&[i16]; 3],
    layer: &Layer,
    planes: &mut Planes,
    mut out: Out,
    n: usize,
) {
    let tiles = &layer.tiles;
    let cout = tiles.halves * LANES;
    planes.split(rows, CIN);
    // SAFETY: by the caller.
    let _session = unsafe { Session::start() };
    let mut parts: Parts = [[[0; LANES]; ROWS]; 4];
    let mut sums = [0i32; BLOCK * 2 * LANES];
    let mut x = 1;
    while x + 1 < n {
        let count = BLOCK.min(n - 1 - x);
        // SAFETY: tiles are configured; the planes hold the block's reads.
        // (Requantising a block while the next one multiplies took 1.1
        // times as long as the two in turn.)
        unsafe { multiply::<CIN>(planes, tiles, x, &mut parts) };
        assemble(&parts, &mut sums, cout);
        finish(layer, &sums[..count * cout], &mut out, x, cout);
        x += count;
    }
}

/// A block's sums as the tiles hold them: the high bytes' products for the
/// two halves of the outputs, then the low bytes', 16 quads by 16 outputs.
type Parts = [[[i32; LANES]; ROWS]; 4];

/// One row of taps' chunk in a block: its windows' high and low bytes and
/// its weights for the outputs' two halves (the second unused for one).
#[repr(C)]
#[derive(Clone, Copy)]
struct Group {
    high: *const u8,
    low: *const u8,
    first: *const i8,
    second: *const i8,
}

/// The windows of output quads `x .. x + 16` times the weights, into
/// `parts`: tiles 0 and 1 sum the high bytes' products for the two halves
/// of the outputs, 2 and 3 the low bytes'; 4 and 5 hold the two bytes'
/// windows, 6 and 7 the weights. One `asm!` block from the first
/// `tilezero` to the last `tilestored`, which loops over the block's
/// [`Group`]s: Rust keeps no promise about registers between blocks.
///
/// # Safety
/// Tiles configured ([`Session`]); the planes split for this layer.
#[inline(always)]
unsafe fn multiply<const CIN: usize>(planes: &Planes, tiles: &Tiles, x: usize, parts: &mut Parts) {
    let none = Group {
        high: std::ptr::null(),
        low: std::ptr::null(),
        first: std::ptr::null(),
        second: std::ptr::null(),
    };
    let mut groups = [none; 6];
    for (i, group) in groups.iter_mut().take(3 * tiles.chunks).enumerate() {
        let (dy, chunk) = (i / tiles.chunks, i % tiles.chunks);
        let at = (x - 1) * CIN + chunk * ROW;
        *group = Group {
            high: planes.high[dy][at..].as_ptr(),
            low: planes.low[dy][at..].as_ptr(),
            first: tiles.tile(dy, chunk, 0),
            second: tiles.tile(dy, chunk, tiles.halves - 1),
        };
    }
    let (g, count, p) = (groups.as_ptr(), 3 * tiles.chunks, parts.as_mut_ptr());
    // SAFETY: by the caller; every tile read lies within the planes
    // ([`Planes::split`]) and the packed weights, and `parts` holds the four
    // tiles stored.
    unsafe {
        if tiles.halves == 2 {
            tile_block!(
                g,
                count,
                p,
                CIN,
                [
                    "mov {a}, [{g} + 24]",
                    "tileloadd tmm7, [{a} + {row}*1]",
                    "tdpbusd tmm1, tmm4, tmm7",
                    "tdpbusd tmm3, tmm5, tmm7",
                ],
                [
                    "tilestored [{p} + {row}*1 + 1024], tmm1",
                    "tilestored [{p} + {row}*1 + 3072], tmm3",
                ]
            );
        } else {
            tile_block!(g, count, p, CIN, [], []);
        }
    }
}

/// The `asm!` block of [`multiply`]: for each of `count` groups at `g`,
/// the windows' two bytes times the first half's weights, then what
/// `second` adds for the second half; the sums stored at `p`, the second
/// half's by `store`.
macro_rules! tile_block {
    ($g:expr, $count:expr, $p:expr, $cin:expr, [$($second:literal),* $(,)?], [$($store:literal),* $(,)?]) => {
        std::arch::asm!(
            "tilezero tmm0",
            "tilezero tmm1",
            "tilezero tmm2",
            "tilezero tmm3",
            "2:",
            "mov {a}, [{g}]",
            "tileloadd tmm4, [{a} + {cin}*1]",
            "mov {a}, [{g} + 8]",
            "tileloadd tmm5, [{a} + {cin}*1]",
            "mov {a}, [{g} + 16]",
            "tileloadd tmm6, [{a} + {row}*1]",
            "tdpbusd tmm0, tmm4, tmm6",
            "tdpbusd tmm2, tmm5, tmm6",
            $($second,)*
            "add {g}, 32",
            "dec {n}",
            "jnz 2b",
            "tilestored [{p} + {row}*1], tmm0",
            "tilestored [{p} + {row}*1 + 2048], tmm2",
            $($store,)*
            g = inout(reg) $g => _,
            n = inout(reg) $count => _,
            a = out(reg) _,
            p = in(reg) $p,
            cin = in(reg) $cin,
            row = in(reg) ROW,
            out("tmm0") _, out("tmm1") _, out("tmm2") _, out("tmm3") _,
            out("tmm4") _, out("tmm5") _, out("tmm6") _, out("tmm7") _,
            options(nostack),
        )
    };
}
use tile_block;

/// Each quad's sums, `cout` of them, from the high and low bytes' parts.
#[inline(always)]
fn assemble(parts: &Parts, sums: &mut [i32], cout: usize) {
    for (m, quad) in sums.chunks_exact_mut(cout).take(BLOCK).enumerate() {
        for (h, half) in quad.chunks_exact_mut(LANES).enumerate() {
            for ((s, &hi), &lo) in half.iter_mut().zip(&parts[h][m]).zip(&parts[2 + h][m]) {
                *s = 256 * hi + lo;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{conv_row as portable, Isa, Network, BLOCK_LAST, BLOCK_WIDE, PADDED};
    use super::super::{LAYERS, QUAD, WIDTH};
    use super::*;

    /// A seeded stream of pseudo-random `u32` (Marsaglia's xorshift).
    fn xorshift(mut seed: u32) -> impl FnMut() -> u32 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        }
    }

    /// Whole rows of each of the shipped network's layers, on the tiles and
    /// in portable code, for widths that end on a whole block, a partial
    /// one or none: the same codes, the same correction.
    #[test]
    fn tile_rows_are_the_portable_rows() {
        if !crate::cpu::has_amx() {
            return;
        }
        let net = Network::fusion_cnn();
        let mut next = xorshift(0x1234_5678);
        let mut planes = Planes::default();
        for n in [1, 2, 3, 17, 18, 19, 33, 50] {
            for (k, layer) in net.layers.iter().enumerate() {
                let cin = if k == 0 { QUAD } else { WIDTH };
                let rows: Vec<Vec<i16>> = (0..3)
                    .map(|_| (0..n * cin).map(|_| (next() % 32768) as i16).collect())
                    .collect();
                let rows = [&rows[0][..], &rows[1][..], &rows[2][..]];
                if k + 1 == LAYERS {
                    let (mut want, mut got) = (vec![0.0f32; n * PADDED], vec![0.0f32; n * PADDED]);
                    let out = |c| Out::Correction(c, 0.5);
                    portable::<WIDTH, 1, BLOCK_LAST>(Isa::Baseline, rows, layer, out(&mut want), n);
                    // SAFETY: `has_amx` above; every AMX CPU has AVX-512.
                    unsafe { conv_row::<WIDTH>(rows, layer, &mut planes, out(&mut got), n) };
                    assert_eq!(got, want, "last layer, {n} quads");
                    continue;
                }
                let (mut want, mut got) = (vec![0i16; n * WIDTH], vec![0i16; n * WIDTH]);
                if k == 0 {
                    portable::<QUAD, 2, BLOCK_WIDE>(
                        Isa::Baseline,
                        rows,
                        layer,
                        Out::Codes(&mut want),
                        n,
                    );
                    unsafe { conv_row::<QUAD>(rows, layer, &mut planes, Out::Codes(&mut got), n) };
                } else {
                    portable::<WIDTH, 2, BLOCK_WIDE>(
                        Isa::Baseline,
                        rows,
                        layer,
                        Out::Codes(&mut want),
                        n,
                    );
                    unsafe { conv_row::<WIDTH>(rows, layer, &mut planes, Out::Codes(&mut got), n) };
                }
                assert_eq!(got, want, "layer {k}, {n} quads");
            }
        }
    }

    /// A block's sums on the tiles against plain 64-bit sums, for each
    /// layer shape the network has, with the widest codes and weights:
    /// a wrong offset, chunk or byte split would show.
    #[test]
    fn tile_sums_are_the_exact_sums() {
        if !crate::cpu::has_amx() {
            return;
        }
        let mut next = xorshift(0x2545_f491);
        for (cin, cout) in [(12, 32), (32, 32), (32, 12)] {
            let n = BLOCK + 5;
            let rows: Vec<Vec<i16>> = (0..3)
                .map(|_| {
                    (0..n * cin)
                        .map(|i| {
                            if i % 7 == 0 {
                                32767
                            } else {
                                (next() % 32768) as i16
                            }
                        })
                        .collect()
                })
                .collect();
            let weights: Vec<i8> = (0..9 * cin * cout)
                .map(|i| {
                    if i % 5 == 0 {
                        -128
                    } else {
                        (next() % 256) as u8 as i8
                    }
                })
                .collect();
            let weight = |t: usize, i: usize, o: usize| weights[(t * cin + i) * cout + o];
            let tiles = Tiles::pack(cin, cout, weight);
            let mut planes = Planes::default();
            planes.split([&rows[0][..], &rows[1][..], &rows[2][..]], cin);
            let mut sums = [0i32; BLOCK * 2 * LANES];
            // SAFETY: `has_amx` above.
            let _session = unsafe { Session::start() };
            let padded = tiles.halves * LANES;
            for x in [1, 3] {
                let mut parts = [[[0; LANES]; ROWS]; 4];
                unsafe {
                    match cin {
                        12 => multiply::<12>(&planes, &tiles, x, &mut parts),
                        _ => multiply::<32>(&planes, &tiles, x, &mut parts),
                    }
                }
                assemble(&parts, &mut sums, padded);
                for m in 0..BLOCK {
                    for o in 0..cout {
                        let want: i64 = (0..9)
                            .map(|t| {
                                let src = &rows[t / 3][(x + m + t % 3 - 1) * cin..][..cin];
                                (0..cin)
                                    .map(|i| i64::from(src[i]) * i64::from(weight(t, i, o)))
                                    .sum::<i64>()
                            })
                            .sum();
                        assert_eq!(
                            i64::from(sums[m * padded + o]),
                            want,
                            "{cin} -> {cout}, x {x}, quad {m}, out {o}"
                        );
                    }
                }
            }
        }
    }
}
