//! What the CPU offers, for kernels that size their register blocking to it.

/// Whether the CPU has AVX-512 (F and VL): 32 vector registers of eight f64, which the
/// DF2T passes, the gammatone groups and the cross-correlation's lag blocks are sized
/// for. Always false with the cargo feature `no-avx512`.
pub fn has_avx512() -> bool {
    #[cfg(all(target_arch = "x86_64", not(feature = "no-avx512")))]
    {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
    }
    #[cfg(any(not(target_arch = "x86_64"), feature = "no-avx512"))]
    {
        false
    }
}
