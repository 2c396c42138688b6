//! What the CPU can do, for kernels that pick a wide build at run time.

/// `true` when the CPU has AVX2 and FMA, the features the wide variants of
/// the row kernels are compiled for (`std` caches the detection).
pub(crate) fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
