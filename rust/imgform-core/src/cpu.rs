//! What the CPU can do, for kernels that pick a wide build at run time.
//!
//! The `IMGFORM_ISA` environment variable, read once, caps the widest build
//! the kernels pick: `baseline`, `avx2`, `avx512` or `amx` (unset: no cap;
//! the Python package warns about other values). Every build gives the scalar
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
    /// AVX-512 and Intel's AMX tiles with their 8-bit products (Xeons
    /// since Sapphire Rapids), which the OS lets the process use: the
    /// network of the "quality" demosaicer multiplies its matrices there.
    Amx,
}

impl Level {
    /// Every level, narrowest first.
    pub const ALL: [Level; 4] = [Level::Baseline, Level::Avx2, Level::Avx512, Level::Amx];

    /// The name `IMGFORM_ISA` takes: `baseline`, `avx2`, `avx512` or `amx`.
    pub fn name(self) -> &'static str {
        match self {
            Level::Baseline => "baseline",
            Level::Avx2 => "avx2",
            Level::Avx512 => "avx512",
            Level::Amx => "amx",
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
            .unwrap_or(Level::Amx)
    })
}

/// Whether the cap lets kernels use `level`'s builds (the CPU must still
/// have the features).
pub(crate) fn allows(level: Level) -> bool {
    level <= cap()
}

/// The widest level this CPU has and the cap allows: what the kernels run.
pub fn level() -> Level {
    if has_avx512() {
        return if amx_capable() {
            Level::Amx
        } else {
            Level::Avx512
        };
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

/// `true` when the CPU has AVX-512 F, BW, DQ and VL besides AVX2 and FMA,
/// the features the `avx512` builds are compiled for, and the cap allows
/// them.
pub(crate) fn has_avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        allows(Level::Avx512)
            && has_avx2_fma()
            && has!("avx512f")
            && has!("avx512bw")
            && has!("avx512dq")
            && has!("avx512vl")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `true` when the CPU has AMX's tiles and 8-bit products, the OS saves
/// their state (XCR0) and the cap allows them: what [`level`] reports. It
/// asks the OS for nothing (see `has_amx`). The tiles' shape is checked
/// too: the kernels use eight of 16 rows of 64 bytes (palette 1 on every
/// CPU so far).
fn amx_capable() -> bool {
    #[cfg(amx)]
    {
        static CAPABLE: OnceLock<bool> = OnceLock::new();
        allows(Level::Amx) && *CAPABLE.get_or_init(amx::capable)
    }
    // Only x86-64 Linux's way of granting the tiles' state is implemented
    // (see the build script).
    #[cfg(not(amx))]
    {
        false
    }
}

/// `true` when kernels may run AMX instructions: [`amx_capable`], and Linux
/// has granted this process the tiles' 8 KB of state, which it hands out
/// only on request (since 5.16; an AMX instruction without it kills the
/// process). The request is made once, the first time a kernel asks, not
/// when the level is read: once granted, Linux refuses alternate signal
/// stacks too small for the tiles' frame in the whole process, which a
/// program that never runs such a kernel should not have imposed on it.
/// Where the request fails (a seccomp filter, a thread's small alternate
/// stack) the kernels run their AVX-512 build, with the same bits.
#[cfg(amx)]
pub(crate) fn has_amx() -> bool {
    static GRANTED: OnceLock<bool> = OnceLock::new();
    amx_capable() && *GRANTED.get_or_init(amx::request)
}

#[cfg(amx)]
mod amx {
    use std::arch::x86_64::{__cpuid_count, CpuidResult};

    /// The CPU's tiles, and the OS's saving of their state.
    pub(super) fn capable() -> bool {
        cpu_has_tiles() && os_saves_tiles()
    }

    fn cpuid(leaf: u32, sub: u32) -> Option<CpuidResult> {
        // SAFETY: CPUID exists on every x86-64 CPU (recent compilers made
        // the function safe; the crate's oldest supported one has it unsafe).
        #[allow(unused_unsafe)]
        let read = |leaf, sub| unsafe { __cpuid_count(leaf, sub) };
        (read(leaf & 0x8000_0000, 0).eax >= leaf).then(|| read(leaf, sub))
    }

    /// AMX-TILE and AMX-INT8 (leaf 7, EDX bits 24 and 25), and palette 1
    /// with eight tiles of 16 rows of 64 bytes (leaf 0x1D).
    fn cpu_has_tiles() -> bool {
        let Some(features) = cpuid(7, 0) else {
            return false;
        };
        let (tile, int8) = ((features.edx >> 24) & 1, (features.edx >> 25) & 1);
        let Some(palette) = cpuid(0x1d, 1) else {
            return false;
        };
        let bytes_per_row = palette.ebx & 0xffff;
        let names = palette.ebx >> 16;
        let rows = palette.ecx & 0xffff;
        tile == 1 && int8 == 1 && bytes_per_row == 64 && names >= 8 && rows >= 16
    }

    /// XCR0's bits 17 and 18 (the tiles' configuration and data), which a
    /// kernel that can save them sets; readable where CPUID's OSXSAVE says
    /// so (leaf 1, ECX bit 27).
    fn os_saves_tiles() -> bool {
        let osxsave = cpuid(1, 0).is_some_and(|r| (r.ecx >> 27) & 1 == 1);
        if !osxsave {
            return false;
        }
        let (low, _high): (u32, u32);
        // SAFETY: XGETBV with ECX 0 reads XCR0, allowed where OSXSAVE is set.
        unsafe {
            std::arch::asm!(
                "xgetbv",
                in("ecx") 0,
                out("eax") low,
                out("edx") _high,
                options(nomem, nostack, preserves_flags),
            );
        }
        (low >> 17) & 0b11 == 0b11
    }

    /// `arch_prctl(ARCH_REQ_XCOMP_PERM, XFEATURE_XTILEDATA)`: 0 when the
    /// kernel grants the tiles' state.
    pub(super) fn request() -> bool {
        const SYS_ARCH_PRCTL: isize = 158;
        const ARCH_REQ_XCOMP_PERM: usize = 0x1023;
        const XFEATURE_XTILEDATA: usize = 18;
        let ret: isize;
        // SAFETY: the system call only changes which state the kernel
        // saves for this process; it reads no memory of ours.
        unsafe {
            std::arch::asm!(
                "syscall",
                inlateout("rax") SYS_ARCH_PRCTL => ret,
                in("rdi") ARCH_REQ_XCOMP_PERM,
                in("rsi") XFEATURE_XTILEDATA,
                lateout("rcx") _,
                lateout("r11") _,
                options(nostack),
            );
        }
        ret == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_are_ordered_and_named_as_the_cap_reads_them() {
        assert!(Level::ALL.windows(2).all(|w| w[0] < w[1]));
        let names = Level::ALL.map(Level::name);
        assert_eq!(names, ["baseline", "avx2", "avx512", "amx"]);
        // What runs is allowed, and AVX2 without the cap's leave is not used.
        assert!(allows(level()));
        assert!(!has_avx2() || allows(Level::Avx2));
    }
}
