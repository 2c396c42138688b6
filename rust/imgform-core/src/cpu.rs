//! What the CPU can do, for kernels that pick a wide build at run time.
//!
//! The `IMGFORM_ISA` environment variable, read once, caps the widest build
//! the kernels pick: `baseline`, `avx2` or `avx512` (unset: no cap; the
//! Python package warns about other values). Every build gives the scalar
//! code's bits (each kernel's tests compare them), so the cap changes only
//! the speed: it lets a wide machine time what a narrower one runs.

use std::sync::OnceLock;

/// An x86-64 instruction-set level the kernels have builds for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// x86-64's SSE2 (or any other architecture).
    Baseline,
    /// AVX2 and FMA.
    Avx2,
    /// AVX-512: F, BW, DQ and VL, and more where a kernel needs it (VBMI
    /// for the 8-bit per-channel resampling).
    Avx512,
}

impl Level {
    /// Every level, narrowest first.
    pub const ALL: [Level; 3] = [Level::Baseline, Level::Avx2, Level::Avx512];

    /// The name `IMGFORM_ISA` takes: `baseline`, `avx2` or `avx512`.
    pub fn name(self) -> &'static str {
        match self {
            Level::Baseline => "baseline",
            Level::Avx2 => "avx2",
            Level::Avx512 => "avx512",
        }
    }
}

/// The level `IMGFORM_ISA` caps the kernels at (none: the widest).
fn cap() -> Level {
    static CAP: OnceLock<Level> = OnceLock::new();
    *CAP.get_or_init(|| {
        let asked = std::env::var("IMGFORM_ISA").unwrap_or_default();
        let asked = asked.trim().to_ascii_lowercase();
        Level::ALL
            .into_iter()
            .find(|l| l.name() == asked)
            .unwrap_or(Level::Avx512)
    })
}

/// Whether the cap lets kernels use `level`'s builds (the CPU must still
/// have the features).
pub(crate) fn allows(level: Level) -> bool {
    level <= cap()
}

/// The widest level this CPU has and the cap allows: what the kernels run.
pub fn level() -> Level {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        let avx512 = has!("avx512f") && has!("avx512bw") && has!("avx512dq") && has!("avx512vl");
        if allows(Level::Avx512) && has_avx2_fma() && avx512 {
            return Level::Avx512;
        }
    }
    if has_avx2_fma() {
        Level::Avx2
    } else {
        Level::Baseline
    }
}

/// `true` when the CPU has AVX2 and the cap allows it (`std` caches the
/// detection).
pub(crate) fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        allows(Level::Avx2) && std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `true` when the CPU has AVX2 and FMA, the features the wide variants of
/// the row kernels are compiled for, and the cap allows them.
pub(crate) fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        has_avx2() && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_are_ordered_and_named_as_the_cap_reads_them() {
        assert!(Level::Baseline < Level::Avx2 && Level::Avx2 < Level::Avx512);
        let names = Level::ALL.map(Level::name);
        assert_eq!(names, ["baseline", "avx2", "avx512"]);
        // What runs is allowed, and AVX2 without the cap's leave is not used.
        assert!(allows(level()));
        assert!(!has_avx2() || allows(Level::Avx2));
    }
}
