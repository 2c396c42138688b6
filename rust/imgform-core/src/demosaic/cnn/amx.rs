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
        // A block's rows read up to 16 quads and 64 bytes on from its
        // first quad.
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
        unsafe { std::arch::asm!("ldtilecfg [{}]", in(reg) CONFIG.0.as_ptr(), options(nostack)) };
        Session
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        // SAFETY: a session exists only where tiles were configured.
        unsafe { std::arch::asm!("tilerelease", options(nostack, nomem)) };
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
        unsafe {
            multiply::<CIN>(planes, tiles, x);
            store(&mut parts);
        }
        assemble(&parts, &mut sums, cout);
        finish(layer, &sums[..count * cout], &mut out, x, cout);
        x += count;
    }
}

/// A block's sums as the tiles hold them: the high bytes' products for the
/// two halves of the outputs, then the low bytes', 16 quads by 16 outputs.
type Parts = [[[i32; LANES]; ROWS]; 4];

/// Multiplies the windows of output quads `x .. x + 16` by the weights,
/// leaving the sums in the tiles: 0 and 1 the high bytes' products for the
/// two halves of the outputs, 2 and 3 the low bytes'. Tiles 4 and 5 hold
/// the two bytes' windows, 6 and 7 the weights.
///
/// # Safety
/// Tiles configured ([`Session`]); the planes split for this layer.
#[inline(always)]
unsafe fn multiply<const CIN: usize>(planes: &Planes, tiles: &Tiles, x: usize) {
    let two = tiles.halves == 2;
    // SAFETY (all blocks): by the caller; every tile read lies within the
    // planes ([`Planes::split`]) and the packed weights.
    unsafe {
        std::arch::asm!(
            "tilezero tmm0",
            "tilezero tmm1",
            "tilezero tmm2",
            "tilezero tmm3",
            options(nostack, nomem)
        )
    };
    for dy in 0..3 {
        for chunk in 0..tiles.chunks {
            let at = (x - 1) * CIN + chunk * ROW;
            let (high, low) = (
                planes.high[dy][at..].as_ptr(),
                planes.low[dy][at..].as_ptr(),
            );
            unsafe {
                std::arch::asm!(
                    "tileloadd tmm6, [{w} + {row}*1]",
                    "tileloadd tmm4, [{high} + {cin}*1]",
                    "tileloadd tmm5, [{low} + {cin}*1]",
                    "tdpbusd tmm0, tmm4, tmm6",
                    "tdpbusd tmm2, tmm5, tmm6",
                    w = in(reg) tiles.tile(dy, chunk, 0),
                    high = in(reg) high,
                    low = in(reg) low,
                    row = in(reg) ROW,
                    cin = in(reg) CIN,
                    options(nostack, readonly),
                )
            };
            if two {
                unsafe {
                    std::arch::asm!(
                        "tileloadd tmm7, [{w} + {row}*1]",
                        "tdpbusd tmm1, tmm4, tmm7",
                        "tdpbusd tmm3, tmm5, tmm7",
                        w = in(reg) tiles.tile(dy, chunk, 1),
                        row = in(reg) ROW,
                        options(nostack, readonly),
                    )
                };
            }
        }
    }
}

/// Stores the sums [`multiply`] left in the tiles.
///
/// # Safety
/// Tiles configured ([`Session`]).
#[inline(always)]
unsafe fn store(parts: &mut Parts) {
    let p = parts.as_mut_ptr().cast::<i32>();
    // SAFETY: by the caller; each tile is 16 rows of 64 bytes, `parts`
    // four of them.
    unsafe {
        std::arch::asm!(
            "tilestored [{p0} + {row}*1], tmm0",
            "tilestored [{p1} + {row}*1], tmm1",
            "tilestored [{p2} + {row}*1], tmm2",
            "tilestored [{p3} + {row}*1], tmm3",
            p0 = in(reg) p,
            p1 = in(reg) p.add(ROWS * LANES),
            p2 = in(reg) p.add(2 * ROWS * LANES),
            p3 = in(reg) p.add(3 * ROWS * LANES),
            row = in(reg) ROW,
            options(nostack),
        )
    };
}

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
    use super::*;

    /// A block's sums on the tiles against plain 64-bit sums, for each
    /// layer shape the network has, with the widest codes and weights:
    /// a wrong offset, chunk or byte split would show.
    #[test]
    fn tile_sums_are_the_exact_sums() {
        if !crate::cpu::has_amx() {
            return;
        }
        let mut seed = 0x2545_f491_u32;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
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
                        12 => multiply::<12>(&planes, &tiles, x),
                        _ => multiply::<32>(&planes, &tiles, x),
                    }
                    store(&mut parts);
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
