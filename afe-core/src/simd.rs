//! One attribute for every SIMD kernel of the workspace: [`simd_kernel!`](crate::simd_kernel).

/// Compiles the function item it wraps once per instruction set and picks the clone for
/// the CPU at run time (`multiversion`): AVX-512 (F and VL) and AVX2, or AVX2 only when
/// the calling crate's `no-avx512` feature is on (the AVX2 path on an AVX-512 host).
/// Kernels written over const-generic lane arrays so get vector code without `unsafe`
/// and give the same bits on every path (each clone runs the same operations in the
/// same order).
///
/// `fma,` before the item adds FMA to the AVX2 clone (AVX-512F implies it), for a
/// kernel that calls `mul_add` and should get the instruction rather than the library
/// call. The calling crate depends on `multiversion` and declares a `no-avx512` feature.
///
/// ```ignore
/// afe_core::simd_kernel!(
///     /// `acc[i] += w·row[i]`.
///     fn axpy(acc: &mut [f64], w: f64, row: &[f64]) {
///         for (a, v) in acc.iter_mut().zip(row) {
///             *a += w * v;
///         }
///     }
/// );
/// ```
#[macro_export]
macro_rules! simd_kernel {
    (fma, $kernel:item) => {
        #[cfg_attr(
            not(feature = "no-avx512"),
            multiversion::multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2+fma"))
        )]
        #[cfg_attr(
            feature = "no-avx512",
            multiversion::multiversion(targets("x86_64+avx2+fma"))
        )]
        $kernel
    };
    ($kernel:item) => {
        #[cfg_attr(
            not(feature = "no-avx512"),
            multiversion::multiversion(targets("x86_64+avx512f+avx512vl", "x86_64+avx2"))
        )]
        #[cfg_attr(
            feature = "no-avx512",
            multiversion::multiversion(targets("x86_64+avx2"))
        )]
        $kernel
    };
}
