//! `butterworth` (not in the AFE): a Butterworth low/high/band-pass/band-stop filter of
//! free order on the time-domain signal of each ear, with the design shared with the IHC.

use afe_core::butter::{butter, butter_sos, round_off_gain, Biquad, ButterType};
use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::filter::Df2t;
use afe_core::{Block, Error, ParamKind, Processor, Result, SignalInfo};

/// Largest `bw_order` accepted: beyond it the roll-off is steeper than double precision
/// resolves.
const MAX_ORDER: u64 = 32;

afe_core::choices! {
    /// The Butterworth filter's response.
    pub enum BwType {
        /// Low-pass.
        Low = "low",
        /// High-pass.
        High = "high",
        /// Band-pass between two cut-offs.
        BandPass = "bandpass",
        /// Band-stop between two cut-offs.
        Stop = "stop",
    }
}

afe_core::params! {
    /// Parameters of the Butterworth filter (`bw_` prefix, in the AFE naming style).
    pub struct ButterworthParams / ButterworthNames {
        /// response type of the Butterworth filter
        #[afe = "bw_type"]
        pub kind: BwType = BwType::Low,
        /// filter order (band designs have twice this order)
        #[afe = "bw_order", kind = ParamKind::CountUpTo(MAX_ORDER)]
        pub order: u32 = 4,
        /// cut-off frequency, or [low, high] for bandpass/stop
        #[afe = "bw_cutoffHz", unit = "Hz"]
        pub cutoff_hz: Vec<f64> = vec![1000.0],
    }
}

impl ButterworthParams {
    /// Order, normalised cut-offs and type, after checking them.
    fn checked(&self, fs: f64) -> Result<(usize, Vec<f64>, ButterType)> {
        let kind = match self.kind {
            BwType::Low => ButterType::Low,
            BwType::High => ButterType::High,
            BwType::BandPass => ButterType::BandPass,
            BwType::Stop => ButterType::BandStop,
        };
        let want = if matches!(kind, ButterType::Low | ButterType::High) {
            1
        } else {
            2
        };
        let nyq = fs / 2.0;
        let fc = &self.cutoff_hz;
        let bad = |reason: String| {
            Error::invalid(
                ButterworthParams::NAMES.cutoff_hz,
                format!("{fc:?}"),
                reason,
            )
        };
        if fc.len() != want {
            return Err(bad(format!(
                "bw_type '{}' takes {want} cut-off frequenc{}",
                self.kind,
                if want == 1 { "y" } else { "ies" }
            )));
        }
        if fc.iter().any(|f| !(*f > 0.0 && *f < nyq)) || (want == 2 && fc[0] >= fc[1]) {
            return Err(bad(format!(
                "cut-offs must be increasing and lie strictly between 0 and the Nyquist frequency ({nyq} Hz)"
            )));
        }
        if u64::from(self.order) > MAX_ORDER {
            return Err(Error::invalid(
                ButterworthParams::NAMES.order,
                self.order,
                "orders above 32 are not supported (the roll-off is then steeper than \
                         double precision resolves)",
            ));
        }
        let wn: Vec<f64> = fc.iter().map(|f| f / nyq).collect();
        Ok((self.order as usize, wn, kind))
    }

    /// The transfer-function `(b, a)` of the design at `fs` Hz, as MATLAB's `butter`.
    pub fn design(&self, fs: f64) -> Result<(Vec<f64>, Vec<f64>)> {
        let (order, wn, kind) = self.checked(fs)?;
        Ok(butter(order, &wn, kind))
    }

    /// The design at `fs` Hz as second-order sections, which the filter runs: stable
    /// at every accepted order and band, where the transfer function is not.
    ///
    /// A design whose sections would amplify their round-off by more than
    /// [`MAX_ROUND_OFF_GAIN`] ([`round_off_gain`]: only wide or high-order band-stops,
    /// e.g. [20, 20000] Hz from order 8 at 44.1 kHz, whose output scipy's sections too
    /// get wrong by 2 % to 1e42) is refused, naming `bw_order` and the highest order
    /// accepted for the band.
    pub fn sections(&self, fs: f64) -> Result<Vec<Biquad>> {
        let (order, wn, kind) = self.checked(fs)?;
        let sections = butter_sos(order, &wn, kind);
        let gain = round_off_gain(&sections, &wn);
        if gain <= MAX_ROUND_OFF_GAIN {
            return Ok(sections);
        }
        let highest = (1..order)
            .rev()
            .find(|&n| round_off_gain(&butter_sos(n, &wn, kind), &wn) <= MAX_ROUND_OFF_GAIN);
        let fix = match highest {
            Some(n) => format!("give an order of at most {n} for this band, or narrow it"),
            None => "narrow the band".into(),
        };
        Err(Error::invalid(
            ButterworthParams::NAMES.order,
            self.order,
            format!(
                "a '{}' design of order {} over {:?} Hz at {fs} Hz cannot be computed in double \
                 precision: its second-order sections would amplify their round-off by \
                 {gain:.1e} (at most {MAX_ROUND_OFF_GAIN:e} is accepted, an error of 1e-5 of \
                 the peak gain); {fix}",
                self.kind, self.order, self.cutoff_hz
            ),
        ))
    }
}

/// Largest [`round_off_gain`] of an accepted design: its round-off reaches the output at
/// up to 1e−5 of the peak gain (ε = 2⁻⁵³ times 1e11).
pub const MAX_ROUND_OFF_GAIN: f64 = 1e11;

/// The Butterworth filter of one ear: time-domain in and out, through a cascade of
/// second-order sections.
#[derive(Debug, Clone)]
pub struct Butterworth {
    sections: Vec<Df2t>,
}

impl Butterworth {
    /// Designs the filter for a time-domain input at `fs` Hz.
    pub fn new(params: &ButterworthParams, fs: f64) -> Result<(Self, SignalInfo)> {
        let sections = params
            .sections(fs)?
            .iter()
            .map(|(b, a)| Df2t::new(b, a, 1))
            .collect();
        Ok((Butterworth { sections }, SignalInfo::time_domain(fs)))
    }
}

impl Processor for Butterworth {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let out = &mut outputs[0];
        out.reset_to(0);
        out.extend_from(inputs[0]);
        for s in &mut self.sections {
            s.process(out.as_mut_slice());
        }
    }

    fn reset(&mut self) {
        self.sections.iter_mut().for_each(Df2t::reset);
    }
}

impl Descriptor for Butterworth {
    type Params = ButterworthParams;
    const NAME: &'static str = "butterworth";
    const DEPENDENCY: &'static str = "time";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str = "Butterworth-filtered ear signals (not in the AFE)";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &ButterworthParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = Butterworth::new(params, inputs[0].fs_hz)?;
        Ok(Built::new(p, vec![out]))
    }
}

/// The registry entry of `butterworth`.
pub static REQUEST: RequestDef = request_def::<Butterworth>();

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::feed;

    fn params(kind: BwType, order: u32, cutoff_hz: &[f64]) -> ButterworthParams {
        ButterworthParams {
            kind,
            order,
            cutoff_hz: cutoff_hz.to_vec(),
        }
    }

    #[test]
    fn each_type_is_its_butter_design_at_the_normalised_cut_offs() {
        let fs = 16000.0;
        for (kind, cutoffs, ty) in [
            (BwType::Low, vec![1000.0], ButterType::Low),
            (BwType::High, vec![3000.0], ButterType::High),
            (BwType::BandPass, vec![500.0, 2000.0], ButterType::BandPass),
            (BwType::Stop, vec![500.0, 2000.0], ButterType::BandStop),
        ] {
            let wn: Vec<f64> = cutoffs.iter().map(|f| f / 8000.0).collect();
            let got = params(kind, 3, &cutoffs).design(fs).expect("valid");
            assert_eq!(got, butter(3, &wn, ty), "{kind}");
        }
    }

    #[test]
    fn cut_offs_lie_strictly_inside_the_band_and_orders_stop_at_32() {
        let fs = 16000.0;
        for ok in [
            params(BwType::Low, 1, &[1.0]),
            params(BwType::Low, 32, &[7999.0]),
            params(BwType::BandPass, 2, &[1000.0, 1001.0]),
        ] {
            assert!(ok.design(fs).is_ok(), "{ok:?}");
        }
        for bad in [
            params(BwType::Low, 2, &[0.0]),
            params(BwType::Low, 2, &[8000.0]),
            params(BwType::High, 2, &[-100.0]),
            params(BwType::Stop, 2, &[1000.0, 1000.0]),
            params(BwType::BandPass, 2, &[2000.0, 1000.0]),
            params(BwType::BandPass, 2, &[1000.0, 8000.0]),
        ] {
            let e = bad.design(fs).expect_err("out of range");
            assert!(
                e.to_string().contains("strictly between 0 and"),
                "{bad:?}: {e}"
            );
        }
        let e = params(BwType::Low, 33, &[1000.0])
            .design(fs)
            .expect_err("order 33");
        assert!(e.to_string().contains("bw_order"), "{e}");
    }

    #[test]
    fn the_processor_runs_the_design_across_chunks() {
        // Order 2: the transfer function is well conditioned, an independent reference
        // for the cascade of sections the processor runs.
        let p = params(BwType::BandPass, 2, &[500.0, 2000.0]);
        let (b, a) = p.design(16000.0).expect("valid");
        let x: Vec<f64> = (0..1000)
            .map(|t| ((t * 7919 % 1000) as f64) / 500.0 - 1.0)
            .collect();
        let mut want = x.clone();
        Df2t::new(&b, &a, 1).process(&mut want);
        let (mut bw, _) = Butterworth::new(&p, 16000.0).expect("valid");
        let got = feed(&mut bw, &x, 1, 1, std::iter::repeat(300));
        assert_eq!(got.len(), want.len());
        for (t, (g, w)) in got.iter().zip(&want).enumerate() {
            assert!((g - w).abs() < 1e-12, "t={t}: {g} vs {w}");
        }
        bw.reset();
        assert_eq!(feed(&mut bw, &x, 1, 1, [300]), &got[..300]);
    }

    /// Issue 44, item 3: the wide band-passes of the issue are accepted; a band-stop
    /// over the same band from order 8 cannot be computed (scipy's sections miss its
    /// output by 2 %) and is refused naming `bw_order` and the highest order accepted.
    #[test]
    fn band_stops_whose_sections_amplify_round_off_are_refused() {
        let fs = 44100.0;
        for (order, band) in [
            (12, [20.0, 20000.0]),
            (8, [5.0, 22000.0]),
            (32, [1.0, 22049.0]),
        ] {
            assert!(
                params(BwType::BandPass, order, &band).sections(fs).is_ok(),
                "{band:?}"
            );
        }
        let msg = params(BwType::Stop, 8, &[20.0, 20000.0])
            .sections(fs)
            .expect_err("round-off")
            .to_string();
        assert!(
            msg.starts_with("invalid value 8 for parameter 'bw_order'")
                && msg.contains("cannot be computed in double precision")
                && msg.contains("give an order of at most"),
            "{msg}"
        );
        let highest: u32 = msg
            .split("at most ")
            .nth(2)
            .and_then(|rest| rest.split(' ').next())
            .and_then(|n| n.parse().ok())
            .expect("the highest order");
        assert!(params(BwType::Stop, highest, &[20.0, 20000.0])
            .sections(fs)
            .is_ok());
    }

    #[test]
    fn cutoff_count_and_range_are_checked() {
        let p = ButterworthParams {
            kind: BwType::BandPass,
            ..Default::default()
        };
        let e = p.design(16000.0).expect_err("one cut-off for a band");
        assert!(e.to_string().contains("takes 2 cut-off frequencies"), "{e}");
        let p = ButterworthParams {
            cutoff_hz: vec![9000.0],
            ..Default::default()
        };
        assert!(p.design(16000.0).is_err());
    }
}
