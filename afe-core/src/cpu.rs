//! What the CPU offers, for kernels that size their register blocking to it, and which
//! instruction set the SIMD kernels run on (for reports of measured speed).

/// Whether the CPU has AVX-512 (F and VL): 32 vector registers of eight f64, which the
/// DF2T passes, the gammatone groups and the cross-correlation's lag blocks are sized
/// for. Always false with the cargo feature `no-avx512`.
pub fn has_avx512() -> bool {
    cfg!(not(feature = "no-avx512")) && cpu_has_avx512()
}

/// Whether the CPU itself has AVX-512 (F and VL), whether or not this build takes it.
pub fn cpu_has_avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The instruction set the SIMD kernels ([`simd_kernel!`](crate::simd_kernel)) run on
/// here: `"avx512"`, `"avx2"` (AVX2 and FMA: also an AVX-512 CPU under the `no-avx512`
/// build) or `"baseline"` (x86-64's SSE2, or another architecture's own).
pub fn simd_path() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    {
        if has_avx512() {
            return "avx512";
        }
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return "avx2";
        }
    }
    "baseline"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_path_follows_the_cpu_and_the_build() {
        let path = simd_path();
        assert_eq!(path == "avx512", has_avx512());
        if cfg!(feature = "no-avx512") {
            assert_ne!(path, "avx512");
        } else {
            assert_eq!(has_avx512(), cpu_has_avx512());
        }
        #[cfg(target_arch = "x86_64")]
        if cpu_has_avx512() {
            // AVX-512F implies AVX2 and FMA
            assert_ne!(path, "baseline");
        }
    }
}
