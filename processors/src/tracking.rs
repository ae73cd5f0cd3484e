//! `tracking`: the sources of the `localisation` tracked over time, live (binauloc's Stage
//! B, `afe_spatial::Tracker`): per localisation frame, up to [`SLOTS`] tracked sources,
//! each with its identity, world azimuth, uncertainty, share of the evidence, velocity
//! and whether front is told from back, the head's yaw, and the head turn they ask for
//! (Stage C, for a neck turning ±90 degrees).
//!
//! The head's yaw comes from its manager's head pose ([`afe_core::HeadPose`]: a CSV
//! track, a motor controller's reports, `Manager.set_head_yaw`), read at each frame's
//! centre; with none, the head is still and its azimuths are the world's. The tracker
//! runs frame by frame on its input, so any chunking gives the output of one call, bit
//! for bit, for the same pose.

use afe_core::descriptor::{request_def, BuildContext, Built, Descriptor, Ears, RequestDef};
use afe_core::{Axis, Block, DrawAs, Error, FromAbove, HeadPose, Processor, Result, SignalInfo};
use afe_spatial::{suggest, Neck, Tracker, TrackerParams};

/// Parameters of the tracking (`trk_*`), declared with the tracker.
pub type TrackingParams = TrackerParams;

/// Tracked sources per output frame, the likeliest first.
pub const SLOTS: usize = 4;

/// The values of each slot, in order.
const SLOT_FIELDS: [&str; 6] = [
    "id",
    "azimuth_deg",
    "uncertainty_deg",
    "mass",
    "velocity_deg_s",
    "resolved",
];

/// The values after the slots: the head's yaw, the suggested turn and the yaw it ends at.
const HEAD_FIELDS: [&str; 3] = ["head_yaw_deg", "suggested_turn_deg", "suggested_yaw_deg"];

/// Values per output frame.
const WIDTH: usize = SLOTS * SLOT_FIELDS.len() + HEAD_FIELDS.len();

/// The tracker over the localisation's frames.
pub struct Tracking {
    tracker: Tracker,
    azimuths: Vec<f64>,
    hop_s: f64,
    /// The first frame's centre, s since the processors started.
    first_s: f64,
    /// Where the first frame's centre lies after its start, s.
    centre_s: f64,
    /// Frames tracked since the start or the last reset.
    frames: u64,
    pose: HeadPose,
    neck: Neck,
    /// The tracks' indices by falling mass, for one frame.
    order: Vec<usize>,
}

impl Tracking {
    /// The tracking of a localisation over `azimuths` (deg) at `frame_rate_hz`, its
    /// frames `window_s` long, the first one starting at `context.started_s`, the head's
    /// yaw read from `context.head_pose`.
    pub fn new(
        params: &TrackingParams,
        azimuths: Vec<f64>,
        frame_rate_hz: f64,
        window_s: f64,
        context: &BuildContext,
    ) -> Result<Self> {
        let hop_s = 1.0 / frame_rate_hz;
        let tracker = Tracker::new(params, hop_s)
            .map_err(|e| Error::InvalidInput(format!("tracking: {e}")))?;
        Ok(Tracking {
            tracker,
            azimuths,
            hop_s,
            first_s: context.started_s + window_s / 2.0,
            centre_s: window_s / 2.0,
            frames: 0,
            pose: context.head_pose.clone(),
            neck: Neck::default(),
            order: Vec::with_capacity(afe_spatial::track::MAX_TRACKS),
        })
    }

    /// Writes the tracks and the turn of the frame just tracked into `row`.
    fn write(&mut self, yaw_deg: f64, row: &mut [f64]) {
        let tracks = self.tracker.tracks();
        self.order.clear();
        self.order.extend(0..tracks.len());
        self.order
            .sort_unstable_by(|&a, &b| tracks[b].mass.total_cmp(&tracks[a].mass));
        row.fill(f64::NAN);
        row[WIDTH - 3] = yaw_deg;
        for (slot, &i) in row.chunks_exact_mut(SLOT_FIELDS.len()).zip(&self.order) {
            let t = &tracks[i];
            slot.copy_from_slice(&[
                t.id as f64,
                t.azimuth_deg,
                t.uncertainty_deg,
                t.mass,
                t.velocity_deg_s,
                if t.resolved { 1.0 } else { 0.0 },
            ]);
        }
        if let Some(s) = suggest(tracks, yaw_deg, &self.neck) {
            row[WIDTH - 2..].copy_from_slice(&[s.turn_deg, s.target_yaw_deg]);
        }
    }
}

impl Processor for Tracking {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let (posterior, activity) = (inputs[0], inputs[1]);
        let n = posterior.frames();
        let out = outputs[0].resize_to(n);
        for (k, row) in out.chunks_exact_mut(WIDTH).enumerate() {
            let t_s = self.first_s + self.frames as f64 * self.hop_s;
            let yaw_deg = self.pose.yaw_at(t_s);
            let active = activity.row(k)[1] > 0.5;
            let scores = active.then(|| posterior.row(k));
            self.tracker.step(t_s, yaw_deg, &self.azimuths, scores);
            self.write(yaw_deg, row);
            self.frames += 1;
        }
    }

    fn reset(&mut self) {
        self.tracker.reset();
        self.frames = 0;
        self.first_s = self.centre_s;
    }
}

impl Descriptor for Tracking {
    type Params = TrackingParams;
    const NAME: &'static str = "tracking";
    const DEPENDENCY: &'static str = "localisation";
    const EARS: Ears = Ears::Binaural;
    const DESCRIPTION: &'static str =
        "the localisation's sources tracked over time, with identities, and the head turn they ask for";
    const OUTPUT_UNIT: &'static str = "deg (azimuths, turns), deg/s (velocities)";

    fn build(params: &TrackingParams, inputs: &[SignalInfo]) -> Result<Built> {
        Self::build_in(params, inputs, &BuildContext::default())
    }

    fn build_in(
        params: &TrackingParams,
        inputs: &[SignalInfo],
        context: &BuildContext,
    ) -> Result<Built> {
        let posterior = &inputs[0];
        let Some(Axis::Azimuth(azimuths)) = posterior.axis("azimuth").cloned() else {
            return Err(Error::InvalidInput(
                "tracking reads the localisation's posterior over azimuth".into(),
            ));
        };
        let window_s = posterior.window_s.unwrap_or(0.0);
        let p = Tracking::new(params, azimuths, posterior.fs_hz, window_s, context)?;
        let mut features: Vec<String> = (1..=SLOTS)
            .flat_map(|k| SLOT_FIELDS.iter().map(move |f| format!("track{k}_{f}")))
            .collect();
        features.extend(HEAD_FIELDS.iter().map(|f| f.to_string()));
        let info = SignalInfo::feature(posterior.fs_hz, posterior.audio_fs_hz, features)
            .drawn_as(DrawAs::Linear)
            .drawn_from_above(FromAbove {
                slots: SLOTS,
                slot_width: SLOT_FIELDS.len(),
                id: 0,
                azimuth: 1,
                uncertainty: 2,
                resolved: 5,
                head_yaw: WIDTH - 3,
                suggested_yaw: WIDTH - 1,
            })
            .with_unit(Self::OUTPUT_UNIT)
            .nan_where("slots without a track, and the suggested turn when none is asked for");
        let info = match posterior.window_s {
            Some(w) => info.with_window_s(w),
            None => info,
        };
        Ok(Built::new(p, vec![info]))
    }
}

/// Registry entry of `tracking`.
pub static REQUEST: RequestDef = request_def::<Tracking>();

#[cfg(test)]
mod tests {
    use super::*;
    use crate::localisation::{Localisation, LocalisationParams};
    use crate::testing::noise;
    use afe_spatial::Head;
    use proptest::prelude::*;

    const FS: f64 = 16000.0;

    /// The localisation of a noise from `azimuth_deg` on the sphere: its posterior and
    /// activity blocks, and the tracking built on their descriptions in `context`.
    fn localised(
        azimuth_deg: f64,
        len: usize,
        context: &BuildContext,
    ) -> (Block, Block, Box<dyn Processor>, SignalInfo) {
        let p = LocalisationParams::default();
        let infos = Localisation::build(&p, &[SignalInfo::time_domain(FS)])
            .expect("localisation")
            .outputs;
        let mut loc = Localisation::new(&p, FS).expect("localisation");
        let head = Head::parse("sphere").expect("sphere");
        let [l, r] = head
            .render(azimuth_deg, &noise(len, 7), FS)
            .expect("render");
        let na = loc.azimuths_deg().len();
        let mut outs = [Block::new(na), Block::new(2)];
        loc.process(&[&Block::from_vec(l, 1), &Block::from_vec(r, 1)], &mut outs);
        let built =
            Tracking::build_in(&TrackingParams::default(), &infos, context).expect("tracking");
        let [post, act] = outs;
        (post, act, built.processor, built.outputs[0].clone())
    }

    /// Runs `tracking` over the frames in chunks of the given sizes (then the rest).
    fn run(tracking: &mut dyn Processor, post: &Block, act: &Block, chunks: &[usize]) -> Vec<f64> {
        let mut out = Vec::new();
        let mut outputs = [Block::new(WIDTH)];
        let (mut at, n) = (0, post.frames());
        for size in chunks.iter().copied().chain(std::iter::once(n)) {
            let end = (at + size).min(n);
            let p = Block::from_vec(
                post.as_slice()[at * post.width()..end * post.width()].to_vec(),
                post.width(),
            );
            let a = Block::from_vec(act.as_slice()[at * 2..end * 2].to_vec(), 2);
            tracking.process(&[&p, &a], &mut outputs);
            out.extend_from_slice(outputs[0].as_slice());
            at = end;
            if at == n {
                break;
            }
        }
        out
    }

    #[test]
    fn a_still_source_on_the_sphere_is_tracked_with_its_image_and_asks_for_a_turn() {
        let (post, act, mut tracking, info) =
            localised(40.0, 2 * FS as usize, &BuildContext::default());
        assert_eq!(info.features().len(), WIDTH);
        assert_eq!(info.features()[1], "track1_azimuth_deg");
        assert_eq!(info.features()[WIDTH - 3], "head_yaw_deg");
        let scene = info.from_above.expect("drawn from above");
        assert_eq!(info.features()[scene.azimuth], "track1_azimuth_deg");
        assert_eq!(
            info.features()[scene.slot_width + scene.resolved],
            "track2_resolved"
        );
        assert_eq!(info.features()[scene.suggested_yaw], "suggested_yaw_deg");
        assert_eq!(info.features()[WIDTH - 2], "suggested_turn_deg");
        assert!(info
            .nan_where
            .is_some_and(|w| w.contains("slots without a track")));
        let out = run(tracking.as_mut(), &post, &act, &[]);
        let last = &out[out.len() - WIDTH..];
        // 40 deg and its image at 140 deg, alike on the sphere; no third source
        let mut found = [last[1], last[SLOT_FIELDS.len() + 1]];
        found.sort_by(f64::total_cmp);
        assert!(
            (found[0] - 40.0).abs() < 3.0 && (found[1] - 140.0).abs() < 3.0,
            "{last:?}"
        );
        assert!(last[2 * SLOT_FIELDS.len()].is_nan(), "{last:?}");
        assert_eq!(
            (last[5], last[SLOT_FIELDS.len() + 5]),
            (0.0, 0.0),
            "unresolved"
        );
        assert_eq!(
            &last[WIDTH - 2..],
            &[20.0, 20.0],
            "a turn to the left asked for"
        );
        // the first frames have no evidence yet: every slot NaN, and no turn
        let first = &out[..WIDTH];
        assert!(
            first
                .iter()
                .enumerate()
                .all(|(i, v)| v.is_nan() == (i != WIDTH - 3)),
            "{first:?}"
        );
    }

    #[test]
    fn a_bad_parameter_is_named() {
        let p = TrackingParams {
            birth: 2.0,
            ..TrackingParams::default()
        };
        let e = Tracking::new(&p, vec![0.0, 180.0], 50.0, 0.04, &BuildContext::default())
            .err()
            .expect("refused");
        assert!(e.to_string().contains(TrackerParams::NAMES.birth), "{e}");
    }

    /// A context whose head turns from 0 to 30 deg over the first second.
    fn turning_head() -> BuildContext {
        let context = BuildContext::default();
        context
            .head_pose
            .set_track(&[(0.0, 0.0), (1.0, 30.0)])
            .expect("track");
        context
    }

    #[test]
    fn the_head_pose_turns_tracks_into_the_world_from_when_the_node_starts() {
        // the head held at 30 deg: the source at 40 deg relative is at 70 in the world,
        // its image (140 relative) at 170
        let context = BuildContext::default();
        context.head_pose.push(0.0, 30.0).expect("yaw");
        let (post, act, mut tracking, _) = localised(40.0, 2 * FS as usize, &context);
        let out = run(tracking.as_mut(), &post, &act, &[]);
        let last = &out[out.len() - WIDTH..];
        let mut found = [last[1], last[SLOT_FIELDS.len() + 1]];
        found.sort_by(f64::total_cmp);
        assert!(
            (found[0] - 70.0).abs() < 3.0 && (found[1] - 170.0).abs() < 3.0,
            "{last:?}"
        );
        assert_eq!(last[WIDTH - 3], 30.0, "the head's yaw");

        // placed 0.5 s into a turn from 0 to 30 deg: its first frame (centre 20 ms in) is
        // read at 0.52 s, and after a reset at 0.02 s
        let mut context = turning_head();
        context.started_s = 0.5;
        let (post, act, mut tracking, _) = localised(40.0, FS as usize / 10, &context);
        let first = run(tracking.as_mut(), &post, &act, &[]);
        assert!(
            (first[WIDTH - 3] - 15.6).abs() < 1e-9,
            "{}",
            first[WIDTH - 3]
        );
        tracking.reset();
        let again = run(tracking.as_mut(), &post, &act, &[]);
        assert!(
            (again[WIDTH - 3] - 0.6).abs() < 1e-9,
            "{}",
            again[WIDTH - 3]
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(8))]
        #[test]
        fn any_chunking_is_bit_identical(chunks in proptest::collection::vec(1usize..40, 1..12)) {
            let context = turning_head();
            let (post, act, mut whole, _) = localised(300.0, FS as usize, &context);
            let (_, _, mut chunked, _) = localised(300.0, FS as usize, &context);
            let one = run(whole.as_mut(), &post, &act, &[]);
            let parts = run(chunked.as_mut(), &post, &act, &chunks);
            prop_assert_eq!(one.len(), parts.len());
            prop_assert!(one.iter().zip(&parts).all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }
}
