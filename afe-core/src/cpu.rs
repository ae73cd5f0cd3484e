//! What the CPU offers, for kernels that size their register blocking to it, and which
//! instruction set the SIMD kernels run on (for reports of measured speed).

/// Whether the CPU has AVX-512 (F and VL): 32 vector registers of eight f64, which the
/// DF2T passes, the gammatone groups and the cross-correlation's lag blocks are sized
/// for. Always false with the cargo feature `no-avx512`, or under `AFE_NO_AVX512=1`
/// ([`avx512_switched_off`]).
pub fn has_avx512() -> bool {
    cfg!(not(feature = "no-avx512")) && cpu_has_avx512() && !avx512_switched_off()
}

/// Whether `AFE_NO_AVX512=1` turned the AVX-512 kernels off on a CPU that has them (and
/// AVX2 and FMA, as every AVX-512 CPU does): the kernels then run their AVX2 clones and
/// the passes are sized for AVX2, as on an AVX2-only CPU, to measure or test that path
/// without a `no-avx512` build. Read once per process; a value other than `1`, `0` or
/// empty is reported on stderr and leaves AVX-512 on.
pub fn avx512_switched_off() -> bool {
    static OFF: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *OFF.get_or_init(|| {
        let asked = std::env::var_os("AFE_NO_AVX512").is_some_and(|v| match v.to_str() {
            Some("1") => true,
            Some("0" | "") => false,
            _ => {
                eprintln!(
                    "AFE_NO_AVX512={}: 1 switches the AVX-512 kernels off, 0 keeps them; \
                     they stay on",
                    v.to_string_lossy()
                );
                false
            }
        });
        asked && cpu_has_avx512() && cpu_has_avx2_fma()
    })
}

/// Whether the CPU has AVX2 and FMA, the AVX2 clones' instruction set.
fn cpu_has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
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
/// here, as their dispatch chose it: `"avx512"`, `"avx2"` (also an AVX-512 CPU under
/// the `no-avx512` build or `AFE_NO_AVX512=1`) or `"baseline"` (x86-64's SSE2, or another architecture's
/// own). The kernels that use FMA take their AVX2 clone only where the CPU also has FMA,
/// as every AVX2 CPU sold has.
pub fn simd_path() -> &'static str {
    match selected() {
        Path::Avx512 => "avx512",
        Path::Avx2 => "avx2",
        Path::Baseline => "baseline",
    }
}

/// A clone of the kernels, by its widest instruction set.
enum Path {
    Avx512,
    Avx2,
    Baseline,
}

crate::simd_kernel!(
    /// The clone the dispatch picked.
    fn selected() -> Path {
        let target = multiversion::target::selected_target!();
        if target.supports_feature_str("avx512f") {
            Path::Avx512
        } else if target.supports_feature_str("avx2") {
            Path::Avx2
        } else {
            Path::Baseline
        }
    }
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_path_is_the_one_the_dispatch_takes() {
        let path = simd_path();
        // the kernels sized for AVX-512 registers are sized so exactly where it runs
        assert_eq!(path == "avx512", has_avx512());
        if cfg!(feature = "no-avx512") || avx512_switched_off() {
            assert_ne!(path, "avx512");
        }
        if std::env::var_os("AFE_NO_AVX512").is_some_and(|v| v == "1") && cpu_has_avx512() {
            assert!(
                avx512_switched_off(),
                "the switch holds on this AVX-512 CPU"
            );
        }
        #[cfg(target_arch = "x86_64")]
        assert_eq!(
            path != "baseline",
            std::arch::is_x86_feature_detected!("avx2"),
            "the AVX2 clone runs wherever the CPU has AVX2"
        );
    }
}
