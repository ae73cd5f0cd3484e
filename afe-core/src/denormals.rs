//! Subnormal numbers flushed to zero while processors run.
//!
//! After digital silence a recursive filter's state decays through the subnormal range
//! (below 2.2e−308): the gammatone's high channels get there within a quarter of a second
//! of zeros, and every filter, hair cell and adaptation stage after them follows. An Intel
//! core handles each vector instruction that produces or reads such a value by a
//! microcode assist ("hundreds of instructions long", Intel's VTune guide; an AMD Zen core
//! hardly pays), so a signal with pauses of true silence ran several times slower on the
//! hosts where speed matters most. Audio engines set the SSE control register's
//! flush-to-zero (FTZ: subnormal results become 0) and denormals-are-zero (DAZ: subnormal
//! inputs read as 0) bits around their processing; so do we, with [`FlushDenormals`] held
//! by every thread while it runs a processor.
//!
//! Only values that would be subnormal change: float64 ones below 2.2e−308, and float32
//! ones below 1.2e−38 where the STFT rounds to single precision, as the AFE does. Every
//! computing thread holds the guard, so the concurrent executor's outputs stay equal to
//! the sequential one's bit for bit, and chunking changes nothing either. The caller's own
//! setting comes back when the guard is dropped: numpy in the same Python thread computes
//! as before.
//!
//! Where the input holds digital silence, the representations normalised frame by frame
//! (the autocorrelation, the pitch's raw values, `precedence`'s ITD and ILD) of frames
//! that only hold such a decay, 280 dB and more below the signal, then differ from the
//! AFE's, which computes them from its arithmetic's last bits. `AFE_KEEP_SUBNORMALS=1` in
//! the environment keeps the IEEE arithmetic, and so the filters' decays as the AFE
//! computes them (read once per process), at the Intel cores' cost.
//!
//! Rust and LLVM assume the default floating-point environment, and the documentation of
//! the deprecated `_mm_setcsr` calls changing these two bits undefined behaviour. We
//! accept that, as audio engines in Rust do: no memory is involved, and what the compiler
//! may do is give a subnormal result the IEEE value where it folds a constant or moves a
//! floating-point operation across the change; the processors run behind `dyn Processor`
//! calls between the change and the restore. Guards must be dropped in the reverse order
//! of their making, as scopes drop them.
//!
//! On other architectures than x86-64 (32-bit x86 is not a target) the guard does
//! nothing: AArch64 cores handle subnormals in hardware at full speed.

use std::marker::PhantomData;
use std::sync::OnceLock;

/// Flush-to-zero (bit 15) and denormals-are-zero (bit 6) of MXCSR.
#[cfg(target_arch = "x86_64")]
const FTZ_DAZ: u32 = 0x8040;

/// Sets FTZ and DAZ on this thread while it lives and restores the thread's previous
/// setting of those two bits when dropped. A guard made where both bits are set already
/// costs one register read and restores nothing. Not `Send`: the setting belongs to the
/// thread that made the guard.
#[must_use = "the setting lasts as long as the guard"]
#[derive(Debug)]
pub struct FlushDenormals {
    /// The control register's value before, when this guard changed it.
    #[cfg(target_arch = "x86_64")]
    saved: Option<u32>,
    _thread: PhantomData<*const ()>,
}

/// Whether processing flushes subnormals to zero: unless `AFE_KEEP_SUBNORMALS` is set to
/// anything but `0` or nothing, read once per process.
pub fn flushing() -> bool {
    static FLUSH: OnceLock<bool> = OnceLock::new();
    *FLUSH.get_or_init(|| {
        std::env::var_os("AFE_KEEP_SUBNORMALS").is_none_or(|v| v.is_empty() || v == "0")
    })
}

impl FlushDenormals {
    /// Flushes subnormal results and inputs to zero on this thread until the guard drops
    /// (unless [`flushing`] is off).
    pub fn enable() -> Self {
        FlushDenormals {
            #[cfg(target_arch = "x86_64")]
            saved: set_ftz_daz(),
            _thread: PhantomData,
        }
    }
}

/// Sets FTZ and DAZ where they were not both set already; returns the register's value
/// before, if it changed it.
#[cfg(target_arch = "x86_64")]
fn set_ftz_daz() -> Option<u32> {
    let csr = mxcsr::read();
    (flushing() && csr & FTZ_DAZ != FTZ_DAZ).then(|| {
        mxcsr::write(csr | FTZ_DAZ);
        csr
    })
}

/// Puts the FTZ and DAZ bits back as `saved` held them; the exception flags raised
/// meanwhile stay.
#[cfg(target_arch = "x86_64")]
fn restore(saved: Option<u32>) {
    if let Some(saved) = saved {
        mxcsr::write((mxcsr::read() & !FTZ_DAZ) | (saved & FTZ_DAZ));
    }
}

impl Drop for FlushDenormals {
    fn drop(&mut self) {
        #[cfg(target_arch = "x86_64")]
        restore(self.saved);
    }
}

/// The IEEE arithmetic (subnormal results and inputs kept: FTZ and DAZ cleared) on this
/// thread while it lives, inside a [`FlushDenormals`]: for the few computations that must
/// give what the AFE's arithmetic gives where values sink into the subnormals (the
/// autocorrelation of a frame that holds only a filter's decay, whose powers underflow in
/// the AFE). The code it covers belongs in a function that is not inlined, so that no
/// floating-point operation moves across the change. Not `Send`.
#[must_use = "the setting lasts as long as the guard"]
#[derive(Debug)]
pub struct GradualUnderflow {
    /// The control register's value before, when this guard changed it.
    #[cfg(target_arch = "x86_64")]
    saved: Option<u32>,
    _thread: PhantomData<*const ()>,
}

impl GradualUnderflow {
    /// Keeps subnormals on this thread until the guard drops.
    pub fn enable() -> Self {
        GradualUnderflow {
            #[cfg(target_arch = "x86_64")]
            saved: {
                let csr = mxcsr::read();
                (csr & FTZ_DAZ != 0).then(|| {
                    mxcsr::write(csr & !FTZ_DAZ);
                    csr
                })
            },
            _thread: PhantomData,
        }
    }
}

/// Sets the subnormal values of `values` to zero (their sign kept), as a flushing thread
/// would have stored them: what a [`GradualUnderflow`] computation hands on keeps the
/// promise that no output holds a subnormal.
pub fn flush_subnormals(values: &mut [f64]) {
    for v in values.iter_mut().filter(|v| v.is_subnormal()) {
        *v = 0f64.copysign(*v);
    }
}

impl Drop for GradualUnderflow {
    fn drop(&mut self) {
        #[cfg(target_arch = "x86_64")]
        restore(self.saved);
    }
}

/// The SSE control and status register, through the instructions that move it (the
/// `_mm_getcsr`/`_mm_setcsr` intrinsics are deprecated in favour of inline assembly).
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod mxcsr {
    pub(super) fn read() -> u32 {
        let mut csr = 0u32;
        // SAFETY: `stmxcsr` stores the 32-bit register into `csr`, a live local; SSE is
        // part of every x86-64 CPU.
        unsafe {
            std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack, preserves_flags));
        }
        csr
    }

    pub(super) fn write(csr: u32) {
        // SAFETY: `ldmxcsr` loads the register from `csr`, a live local; the values
        // written differ from the thread's own only in the FTZ and DAZ bits, which
        // change no memory and raise no exception (the compiler's model of the
        // floating-point environment: see the module's doc).
        unsafe {
            std::arch::asm!(
                "ldmxcsr [{}]",
                in(reg) &csr,
                options(nostack, readonly, preserves_flags)
            );
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use std::hint::black_box;

    /// Half the smallest normal number, computed at run time.
    fn halved() -> f64 {
        black_box(f64::MIN_POSITIVE) * black_box(0.5)
    }

    #[test]
    fn subnormals_are_zero_inside_the_guard_and_come_back_after() {
        if !flushing() {
            return eprintln!("AFE_KEEP_SUBNORMALS is set: the guard does nothing");
        }
        assert!(
            halved().is_subnormal(),
            "the test thread starts without FTZ"
        );
        let subnormal = halved();
        {
            let _outer = FlushDenormals::enable();
            assert_eq!(halved(), 0.0, "results flushed (FTZ)");
            assert_eq!(
                black_box(subnormal) * black_box(4.0),
                0.0,
                "inputs read as 0 (DAZ)"
            );
            {
                let _inner = FlushDenormals::enable();
                assert_eq!(halved(), 0.0);
            }
            assert_eq!(
                halved(),
                0.0,
                "an inner guard leaves the outer one's setting"
            );
            assert_eq!(
                black_box(3.0e-300) * black_box(2.0),
                6.0e-300,
                "normal values untouched"
            );
        }
        assert!(halved().is_subnormal(), "the thread's setting restored");
        assert_eq!(
            black_box(subnormal) * black_box(4.0),
            2.0 * f64::MIN_POSITIVE
        );
    }

    #[test]
    fn gradual_underflow_keeps_subnormals_inside_a_flushing_guard() {
        if !flushing() {
            return eprintln!("AFE_KEEP_SUBNORMALS is set: the flushing guard does nothing");
        }
        let subnormal = halved();
        let _flush = FlushDenormals::enable();
        assert_eq!(halved(), 0.0);
        {
            let _ieee = GradualUnderflow::enable();
            assert!(halved().is_subnormal(), "results kept");
            assert_eq!(
                black_box(subnormal) * black_box(4.0),
                2.0 * f64::MIN_POSITIVE,
                "inputs read as they are"
            );
        }
        assert_eq!(halved(), 0.0, "the flushing setting back after it");
    }

    #[test]
    fn flushing_values_zeroes_the_subnormals_only() {
        let tiny = f64::MIN_POSITIVE / 4.0;
        let mut v = [tiny, -tiny, f64::MIN_POSITIVE, 1.0, f64::NAN, 0.0];
        flush_subnormals(&mut v);
        assert_eq!(v[0].to_bits(), 0f64.to_bits());
        assert_eq!(v[1].to_bits(), (-0f64).to_bits());
        assert_eq!(v[2..4], [f64::MIN_POSITIVE, 1.0]);
        assert!(v[4].is_nan());
    }

    #[test]
    fn a_thread_that_had_ftz_keeps_it() {
        if !flushing() {
            return eprintln!("AFE_KEEP_SUBNORMALS is set: the guard does nothing");
        }
        let _own = FlushDenormals::enable();
        drop(FlushDenormals::enable());
        assert_eq!(halved(), 0.0);
    }
}
