//! The machine a measurement ran on, for the reports of `afe bench` and `afe stream`:
//! speed figures are only comparable with the CPU and instruction set they came from.

use serde::Serialize;

/// The CPU, its logical cores and the instruction set the kernels take.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Host {
    /// The CPU's model name (Linux's `/proc/cpuinfo`), or the architecture where that
    /// is not known.
    pub cpu: String,
    /// Logical cores this process may use.
    pub cores: usize,
    /// The SIMD kernels' instruction set: `avx512`, `avx2` or `baseline`.
    pub simd: &'static str,
    /// Whether the CPU has AVX-512, so that `simd: avx2` with `avx512_available: true`
    /// is the forced AVX2 path of a `no-avx512` build.
    pub avx512_available: bool,
    /// The version of this crate.
    pub version: &'static str,
}

impl Host {
    /// Describes the machine this runs on.
    pub fn detect() -> Self {
        Host {
            cpu: cpu_model().unwrap_or_else(|| std::env::consts::ARCH.to_string()),
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            simd: afe_core::cpu::simd_path(),
            avx512_available: afe_core::cpu::cpu_has_avx512(),
            version: env!("CARGO_PKG_VERSION"),
        }
    }

    /// One line for a person: `AMD EPYC, 2 cores, avx512`, with `(AVX-512 off)` on
    /// the forced AVX2 path.
    pub fn describe(&self) -> String {
        let forced = if self.avx512_available && self.simd != "avx512" {
            " (AVX-512 off)"
        } else {
            ""
        };
        format!("{}, {} cores, {}{forced}", self.cpu, self.cores, self.simd)
    }
}

/// The first `model name` of `/proc/cpuinfo`.
fn cpu_model() -> Option<String> {
    let info = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    model_name(&info)
}

fn model_name(cpuinfo: &str) -> Option<String> {
    cpuinfo.lines().find_map(|line| {
        let (key, value) = line.split_once(':')?;
        let value = value.trim();
        (key.trim() == "model name" && !value.is_empty()).then(|| value.to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_name_is_read_off_cpuinfo() {
        let info = "processor\t: 0\nvendor_id\t: GenuineIntel\nmodel name\t: Intel(R) Xeon(R) \
                    Platinum 8375C CPU @ 2.90GHz\nflags\t\t: fpu avx2\n\nprocessor\t: 1\n\
                    model name\t: other\n";
        assert_eq!(
            model_name(info).as_deref(),
            Some("Intel(R) Xeon(R) Platinum 8375C CPU @ 2.90GHz")
        );
        assert_eq!(model_name("processor\t: 0\nmodel name\t:\n"), None);
        assert_eq!(model_name(""), None);
    }

    #[test]
    fn the_description_names_a_forced_avx2_path() {
        let mut host = Host {
            cpu: "Xeon".into(),
            cores: 2,
            simd: "avx2",
            avx512_available: true,
            version: "0",
        };
        assert_eq!(host.describe(), "Xeon, 2 cores, avx2 (AVX-512 off)");
        host.avx512_available = false;
        assert_eq!(host.describe(), "Xeon, 2 cores, avx2");
        let here = Host::detect();
        assert!(here.cores >= 1 && !here.cpu.is_empty());
    }
}
