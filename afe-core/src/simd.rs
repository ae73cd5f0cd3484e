//! One attribute for every SIMD kernel of the workspace: [`simd_kernel!`](crate::simd_kernel).

/// Compiles the function item it wraps once per instruction set and picks the clone for
/// the CPU at run time (`multiversion`): AVX-512 (F and VL) and AVX2, or AVX2 only when
/// the calling crate's `no-avx512` feature is on. A second AVX2 set is what an AVX-512 CPU
/// runs under `AFE_NO_AVX512=1` ([`avx512_switched_off`](crate::cpu::avx512_switched_off)):
/// the AVX2 path on an AVX-512 host, in the same build.
/// Kernels written over const-generic lane arrays so get vector code without `unsafe`
/// and give the same bits on every path (each clone runs the same operations in the
/// same order).
///
/// `fma,` before the item adds FMA to the AVX2 clone (AVX-512F implies it), for a
/// kernel that calls `mul_add` and should get the instruction rather than the library
/// call. The item is a free function whose argument types name their generics (no
/// `impl Trait`); the calling crate depends on `multiversion` and declares a `no-avx512`
/// feature.
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
        #[$crate::simd::kernel(fma)]
        $kernel
    };
    ($kernel:item) => {
        #[$crate::simd::kernel]
        $kernel
    };
}

#[doc(hidden)]
pub use afe_simd_macro::kernel;
