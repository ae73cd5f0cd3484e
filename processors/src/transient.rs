//! `onsetStrength` and `offsetStrength`: the frame-to-frame rise (onset) or fall (offset)
//! of the ratemap level in dB, clipped to a maximum (specs 23-onset and 24-offset).
//!
//! The two requests differ only in the sign of the change they keep and in their
//! parameter, so one processor computes both.

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::{Block, Error, Processor, Result, SignalInfo};

afe_core::params! {
    /// Parameters of the onset strength, under their AFE names.
    pub struct OnsetParams / OnsetNames {
        /// upper limit of the onset strength
        #[afe = "ons_maxOnsetdB", unit = "dB"]
        pub max_onset_db: f64 = 30.0,
    }
}

afe_core::params! {
    /// Parameters of the offset strength, under their AFE names.
    pub struct OffsetParams / OffsetNames {
        /// upper limit of the offset strength (its absolute value is used)
        #[afe = "ofs_maxOffsetdB", unit = "dB"]
        pub max_offset_db: f64 = 30.0,
    }
}

/// Which level change a [`TransientStrength`] keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Direction {
    /// Rises: `min(max(d, 0), max)`.
    Onset,
    /// Falls, as positive dB: `min(|min(d, 0)|, max)`.
    Offset,
}

/// Onset or offset strength of one ear: ratemap `[frame][channel]` in, dB of the same
/// shape out (≥ 0).
///
/// The level is `10·log10` of the ratemap whatever its scaling; a ratemap value of 0 is
/// −∞ dB, a negative one NaN. Differences that are NaN (−∞ − −∞, or a negative ratemap)
/// count as no change, following MATLAB's NaN-ignoring `max`/`min`.
#[derive(Debug, Clone)]
pub struct TransientStrength {
    direction: Direction,
    /// The clipping limit in dB (≥ 0).
    max_db: f64,
    /// Level in dB of the last frame of the previous chunk; empty before the first frame.
    prev_db: Vec<f64>,
}

impl TransientStrength {
    /// Builds the onset strength for the ratemap `input`.
    pub fn onset(params: &OnsetParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        if params.max_onset_db.is_nan() || params.max_onset_db < 0.0 {
            return Err(Error::invalid(
                OnsetParams::NAMES.max_onset_db,
                params.max_onset_db,
                "must be at least 0 dB",
            ));
        }
        Ok(Self::new(Direction::Onset, params.max_onset_db, input))
    }

    /// Builds the offset strength for the ratemap `input`.
    pub fn offset(params: &OffsetParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        if !params.max_offset_db.is_finite() {
            return Err(Error::invalid(
                OffsetParams::NAMES.max_offset_db,
                params.max_offset_db,
                "must be a finite number of dB",
            ));
        }
        Ok(Self::new(
            Direction::Offset,
            params.max_offset_db.abs(),
            input,
        ))
    }

    fn new(direction: Direction, max_db: f64, input: &SignalInfo) -> (Self, SignalInfo) {
        let strength = TransientStrength {
            direction,
            max_db,
            prev_db: Vec::with_capacity(input.channels()),
        };
        (strength, input.framed(input.fs_hz))
    }
}

impl Processor for TransientStrength {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let x = inputs[0];
        let nc = x.width();
        let out = outputs[0].resize_to(x.frames());
        if x.is_empty() {
            return;
        }
        if self.prev_db.is_empty() {
            self.prev_db
                .extend(x.row(0).iter().map(|v| 10.0 * v.log10()));
        }
        for (row, o) in x.rows().zip(out.chunks_exact_mut(nc)) {
            for ((v, prev), o) in row.iter().zip(self.prev_db.iter_mut()).zip(o) {
                let level = 10.0 * v.log10();
                let d = level - *prev;
                *o = match self.direction {
                    Direction::Onset => d.max(0.0).min(self.max_db),
                    Direction::Offset => d.min(0.0).abs().min(self.max_db),
                };
                *prev = level;
            }
        }
    }

    fn reset(&mut self) {
        self.prev_db.clear();
    }
}

/// The `onsetStrength` request (spec 23-onset).
pub struct OnsetStrength;

impl Descriptor for OnsetStrength {
    type Params = OnsetParams;
    const NAME: &'static str = "onsetStrength";
    const DEPENDENCY: &'static str = "ratemap";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "rise of the ratemap level from the previous frame, per frame and channel";
    const OUTPUT_UNIT: &'static str = "dB";

    fn build(params: &OnsetParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = TransientStrength::onset(params, &inputs[0])?;
        Ok(Built::new(p, vec![out.with_unit(Self::OUTPUT_UNIT)]))
    }
}

/// The `offsetStrength` request (spec 24-offset).
pub struct OffsetStrength;

impl Descriptor for OffsetStrength {
    type Params = OffsetParams;
    const NAME: &'static str = "offsetStrength";
    const DEPENDENCY: &'static str = "ratemap";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str =
        "fall of the ratemap level from the previous frame, per frame and channel";
    const OUTPUT_UNIT: &'static str = "dB";

    fn build(params: &OffsetParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = TransientStrength::offset(params, &inputs[0])?;
        Ok(Built::new(p, vec![out.with_unit(Self::OUTPUT_UNIT)]))
    }
}

/// The registry entry of `onsetStrength`.
pub static ONSET_REQUEST: RequestDef = request_def::<OnsetStrength>();
/// The registry entry of `offsetStrength`.
pub static OFFSET_REQUEST: RequestDef = request_def::<OffsetStrength>();

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ratemap_info(channels: usize) -> SignalInfo {
        SignalInfo::time_frequency(
            44100.0,
            (0..channels).map(|c| 100.0 * (c + 1) as f64).collect(),
        )
        .framed(100.0)
    }

    fn run(p: &mut TransientStrength, data: &[f64], nc: usize) -> Vec<f64> {
        let mut out = vec![Block::new(nc)];
        p.process(&[&Block::from_vec(data.to_vec(), nc)], &mut out);
        out[0].as_slice().to_vec()
    }

    #[test]
    fn bad_limits_name_their_parameter() {
        let info = ratemap_info(2);
        let e = TransientStrength::onset(&OnsetParams { max_onset_db: -1.0 }, &info)
            .unwrap_err()
            .to_string();
        assert!(e.contains("ons_maxOnsetdB"), "{e}");
        assert!(TransientStrength::onset(&OnsetParams { max_onset_db: 0.0 }, &info).is_ok());
        let p = OffsetParams {
            max_offset_db: f64::NAN,
        };
        let e = TransientStrength::offset(&p, &info)
            .unwrap_err()
            .to_string();
        assert!(e.contains("ofs_maxOffsetdB"), "{e}");
    }

    #[test]
    fn rises_and_falls_in_db_with_the_infinite_cases() {
        // One channel: 1 → 10 (+10 dB) → 0.1 (−20 dB) → 0 (−∞) → 0 (NaN) → 1e5 (+∞).
        let x = [1.0, 10.0, 0.1, 0.0, 0.0, 1e5];
        let info = ratemap_info(1);
        let (mut on, out_info) =
            TransientStrength::onset(&OnsetParams::default(), &info).expect("valid");
        assert_eq!(out_info, info);
        assert_eq!(run(&mut on, &x, 1), [0.0, 10.0, 0.0, 0.0, 0.0, 30.0]);
        let p = OffsetParams {
            max_offset_db: -25.0,
        };
        let (mut off, _) = TransientStrength::offset(&p, &info).expect("valid");
        let got = run(&mut off, &x, 1);
        assert_eq!(got[..2], [0.0, 0.0]);
        assert!((got[2] - 20.0).abs() < 1e-12);
        assert_eq!(got[3..], [25.0, 0.0, 0.0]);
    }

    #[test]
    fn empty_chunks_keep_the_state_and_reset_clears_it() {
        let (mut on, _) =
            TransientStrength::onset(&OnsetParams::default(), &ratemap_info(1)).expect("valid");
        assert_eq!(run(&mut on, &[1.0], 1), [0.0]);
        assert!(run(&mut on, &[], 1).is_empty());
        assert_eq!(run(&mut on, &[10.0], 1), [10.0]);
        on.reset();
        assert_eq!(run(&mut on, &[100.0], 1), [0.0]);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

        /// Random chunkings of a random ratemap (zeros included) give the one-call output
        /// bit for bit, for both directions.
        #[test]
        fn any_chunking_is_bit_identical(
            data in prop::collection::vec(prop_oneof![Just(0.0), 1e-6f64..10.0], 3 * 40),
            cuts in prop::collection::vec(0usize..=40, 0..8),
        ) {
            let nc = 3;
            let info = ratemap_info(nc);
            let makers: [fn(&SignalInfo) -> TransientStrength; 2] = [
                |i| TransientStrength::onset(&OnsetParams::default(), i).expect("valid").0,
                |i| TransientStrength::offset(&OffsetParams::default(), i).expect("valid").0,
            ];
            for make in makers {
                let whole = run(&mut make(&info), &data, nc);
                let mut p = make(&info);
                let mut bounds = cuts.clone();
                bounds.extend([0, 40]);
                bounds.sort_unstable();
                let mut chunked = Vec::new();
                for w in bounds.windows(2) {
                    chunked.extend(run(&mut p, &data[w[0] * nc..w[1] * nc], nc));
                }
                prop_assert_eq!(&whole, &chunked);
            }
        }
    }
}
