//! `localisation`: where the sound comes from, per frame: a posterior over head-relative
//! azimuth (0 = front, 90 = left, as in SOFA) from the projection of both ears' spectra
//! on the head's transfer functions (training-free, as binauloc's Stage A;
//! `afe_spatial::Localiser`), and each frame's activity.
//!
//! Each frame's score per azimuth (the share of the band's energy along that
//! direction's steering vector) is normalised to sum to 1: a silent frame gets the
//! uniform posterior. A frame is active when its band level is within `loc_activityDb`
//! of the loudest frame so far (a running peak, so the output does not depend on what
//! comes later); frames are cut from both ears with one frame buffer, so any chunking
//! gives the output of one call, bit for bit.

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::{Axis, Block, DrawAs, Error, Processor, Result, SignalInfo};
use afe_spatial::{Head, Localiser, LocaliserParams};

use crate::framed::EarFrames;

/// Parameters of the localisation: the head and the localiser's own (frame, hop, band,
/// grid step, activity), declared with the localiser.
pub type LocalisationParams = LocaliserParams;

/// The posterior over azimuth and the activity of each frame of both ears.
pub struct Localisation {
    localiser: Localiser,
    frames: EarFrames,
    /// One frame of each ear, contiguous.
    ears: [Vec<f64>; 2],
    /// Ratio to the loudest band energy so far under which a frame is inactive.
    floor: f64,
    /// The loudest band energy so far.
    loudest: f64,
    /// Multiply-adds per second of input, for the graph's work limit.
    work_per_second: f64,
}

/// Band level of a silent frame, dB.
const SILENT_DB: f64 = -300.0;

impl Localisation {
    /// Builds the localisation of `p.head` for ears at `fs_hz`.
    pub fn new(p: &LocalisationParams, fs_hz: f64) -> Result<Self> {
        let head = Head::parse(&p.head)
            .map_err(|e| Error::invalid(LocaliserParams::NAMES.head, &p.head, e.to_string()))?;
        let localiser = Localiser::new(&head, fs_hz, p)
            .map_err(|e| Error::InvalidInput(format!("localisation: {e}")))?;
        let w = localiser.frame_len();
        let work_per_second = fs_hz / localiser.hop() as f64 * localiser.work_per_frame() as f64;
        Ok(Localisation {
            work_per_second,
            frames: EarFrames::new(1, w, localiser.hop()),
            ears: [vec![0.0; w], vec![0.0; w]],
            floor: 10f64.powf(-p.activity_db / 10.0),
            loudest: 0.0,
            localiser,
        })
    }

    /// The azimuths of the posterior, deg.
    pub fn azimuths_deg(&self) -> &[f64] {
        self.localiser.azimuths_deg()
    }
}

impl Processor for Localisation {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let ears = (inputs[0].as_slice(), inputs[1].as_slice());
        let n = self.frames.available(ears.0, ears.1);
        let (posterior, activity) = outputs.split_at_mut(1);
        let posterior = posterior[0].resize_to(n);
        let activity = activity[0].resize_to(n);
        let na = self.localiser.azimuths_deg().len();
        for (k, (row, act)) in posterior
            .chunks_exact_mut(na)
            .zip(activity.chunks_exact_mut(2))
            .enumerate()
        {
            let (left, right) = self.frames.frame(ears, k);
            for (frame, ear) in [left, right].into_iter().zip(&mut self.ears) {
                for (e, x) in ear.iter_mut().zip(frame.rows()) {
                    *e = x[0];
                }
            }
            let energy = self
                .localiser
                .score(&self.ears[0], &self.ears[1], row)
                .energy;
            let total: f64 = row.iter().sum();
            if total > 0.0 {
                row.iter_mut().for_each(|s| *s /= total);
            } else {
                row.fill(1.0 / na as f64);
            }
            self.loudest = self.loudest.max(energy);
            let active = energy > 0.0 && energy >= self.floor * self.loudest;
            act[0] = if energy > 0.0 {
                10.0 * energy.log10()
            } else {
                SILENT_DB
            };
            act[1] = if active { 1.0 } else { 0.0 };
        }
        self.frames.advance(ears.0, ears.1, n);
    }

    /// The projection's multiply-adds (a short hop over a fine grid asks for billions per
    /// second: found by fuzzing, 30 s for one case).
    fn hidden_work_per_second(&self) -> f64 {
        self.work_per_second
    }

    fn reset(&mut self) {
        self.frames.reset();
        self.localiser.reset();
        self.loudest = 0.0;
    }
}

impl Descriptor for Localisation {
    type Params = LocalisationParams;
    const NAME: &'static str = "localisation";
    const DEPENDENCY: &'static str = "time";
    const EARS: Ears = Ears::Binaural;
    const DESCRIPTION: &'static str =
        "posterior over head-relative azimuth per frame, by projection on the head's transfer functions";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &LocalisationParams, inputs: &[SignalInfo]) -> Result<Built> {
        let input = &inputs[0];
        let p = Localisation::new(params, input.fs_hz)?;
        let rate = input.fs_hz / p.localiser.hop() as f64;
        let window_s = params.w_size_sec;
        let posterior = SignalInfo::feature(rate, input.audio_fs_hz, Vec::new());
        let posterior = SignalInfo {
            axes: vec![Axis::Azimuth(p.azimuths_deg().to_vec())],
            ..posterior
        }
        .with_window_s(window_s);
        let activity = SignalInfo::feature(
            rate,
            input.audio_fs_hz,
            vec!["level_db".to_string(), "active".to_string()],
        )
        .with_window_s(window_s)
        .drawn_as(DrawAs::Linear)
        .named("localisation_activity");
        Ok(Built::new(p, vec![posterior, activity]))
    }
}

/// Registry entry of `localisation`.
pub static REQUEST: RequestDef = request_def::<Localisation>();

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::noise;
    use afe_core::{Panel, Scale};
    use afe_spatial::locate::lateral_deg;
    use proptest::prelude::*;

    const FS: f64 = 16000.0;

    fn build(p: &LocalisationParams) -> (Localisation, Vec<SignalInfo>) {
        let built = Localisation::build(p, &[SignalInfo::time_domain(FS)]).expect("built");
        (Localisation::new(p, FS).expect("valid"), built.outputs)
    }

    /// Runs `loc` over both ears in chunks of the given sizes (then the rest); returns
    /// the posterior and the activity, joined.
    fn run(loc: &mut Localisation, ears: &[Vec<f64>; 2], chunks: &[usize]) -> (Vec<f64>, Vec<f64>) {
        let (mut post, mut act) = (Vec::new(), Vec::new());
        let na = loc.azimuths_deg().len();
        let mut outputs = [Block::new(na), Block::new(2)];
        let mut at = 0;
        let len = ears[0].len();
        for size in chunks.iter().copied().chain(std::iter::once(len)) {
            let end = (at + size).min(len);
            let l = Block::from_vec(ears[0][at..end].to_vec(), 1);
            let r = Block::from_vec(ears[1][at..end].to_vec(), 1);
            loc.process(&[&l, &r], &mut outputs);
            post.extend_from_slice(outputs[0].as_slice());
            act.extend_from_slice(outputs[1].as_slice());
            at = end;
            if at == len {
                break;
            }
        }
        (post, act)
    }

    fn rendered(azimuth_deg: f64, len: usize) -> [Vec<f64>; 2] {
        let head = Head::parse("sphere").expect("sphere");
        head.render(azimuth_deg, &noise(len, 3), FS)
            .expect("render")
    }

    #[test]
    fn a_sphere_render_peaks_at_its_azimuth_and_the_description_says_so() {
        let (mut loc, infos) = build(&LocalisationParams::default());
        let ears = rendered(60.0, 8000);
        let (post, act) = run(&mut loc, &ears, &[]);
        let az = loc.azimuths_deg().to_vec();
        let frames = post.len() / az.len();
        assert_eq!(frames, act.len() / 2);
        assert!(frames >= 20, "{frames} frames");
        for (t, row) in post.chunks_exact(az.len()).enumerate().skip(2) {
            assert!(
                (row.iter().sum::<f64>() - 1.0).abs() < 1e-12,
                "frame {t} sums to 1"
            );
            let best = (0..row.len())
                .max_by(|&a, &b| row[a].total_cmp(&row[b]))
                .unwrap_or(0);
            let err = (lateral_deg(az[best]) - 60.0).abs();
            assert!(err <= 2.0, "frame {t}: {}", az[best]);
        }
        assert!(
            act.chunks_exact(2).skip(1).all(|a| a[1] == 1.0),
            "noise is active"
        );
        let d = &infos[0];
        assert_eq!(d.axis_names(), ["frame", "azimuth"]);
        assert_eq!((d.fs_hz, d.window_s), (50.0, Some(0.04)));
        let plan = d.plan();
        assert_eq!((plan.panel, plan.scale), (Panel::OverTime, Scale::Linear));
        assert_eq!(plan.rows.expect("azimuths up").label, "azimuth (deg)");
        assert_eq!(infos[1].name, Some("localisation_activity"));
        assert_eq!(infos[1].features(), ["level_db", "active"]);
    }

    #[test]
    fn silence_is_uniform_and_inactive_and_quiet_frames_after_loud_ones_inactive() {
        let (mut loc, _) = build(&LocalisationParams::default());
        let mut ears = rendered(300.0, 6400);
        for ear in &mut ears {
            ear[..1600].fill(0.0);
            ear[4000..].iter_mut().for_each(|v| *v *= 1e-3);
        }
        let (post, act) = run(&mut loc, &ears, &[]);
        let na = loc.azimuths_deg().len();
        assert!(
            post[..na].iter().all(|&p| p == 1.0 / na as f64),
            "silence: uniform"
        );
        assert_eq!((act[0], act[1]), (SILENT_DB, 0.0));
        let last = act.len() / 2 - 1;
        assert_eq!(
            act[2 * last + 1],
            0.0,
            "60 dB down after the loud part: inactive"
        );
        assert!(act[2 * 5 + 1] == 1.0, "the loud part is active");
    }

    #[test]
    fn a_bad_head_or_window_is_named() {
        let bad = |p: LocalisationParams| {
            Localisation::new(&p, FS)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default()
        };
        let e = bad(LocalisationParams {
            head: "dummy".into(),
            ..LocalisationParams::default()
        });
        assert!(
            e.contains("'loc_head'") && e.contains("unknown head 'dummy'"),
            "{e}"
        );
        let e = bad(LocalisationParams {
            w_size_sec: 5.0,
            ..LocalisationParams::default()
        });
        assert!(e.contains("loc_wSizeSec"), "{e}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(6))]
        /// Any chunking gives the output of one call, bit for bit.
        #[test]
        fn chunk_invariant(chunks in proptest::collection::vec(1usize..900, 1..12)) {
            let ears = rendered(130.0, 4000);
            let (mut one, _) = build(&LocalisationParams::default());
            let whole = run(&mut one, &ears, &[]);
            let (mut many, _) = build(&LocalisationParams::default());
            prop_assert_eq!(run(&mut many, &ears, &chunks), whole);
        }
    }
}
