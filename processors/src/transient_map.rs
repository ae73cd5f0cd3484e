//! `onsetMap` and `offsetMap`: binary time-frequency maps of salient transients, the
//! peaks over time of the onset (offset) strength that are strong enough, apart in time,
//! and part of a connected structure of enough cells (spec 25-onsetMap-offsetMap).
//!
//! Both requests run the same processor on their strength; they share the `trm_*`
//! parameters.

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::{Block, Error, ParamKind, Processor, Result, SignalInfo, SignalKind};

afe_core::params! {
    /// Parameters of the transient maps, under their AFE names.
    pub struct TransientMapParams / TransientMapNames {
        /// minimum transient strength
        #[afe = "trm_minStrengthdB", unit = "dB"]
        pub min_strength_db: f64 = 3.0,
        /// minimum number of time-frequency cells of a connected transient
        #[afe = "trm_minSpread", kind = ParamKind::Count]
        pub min_spread: u64 = 5,
        /// peaks closer than this in time are fused (the strongest is kept)
        #[afe = "trm_fuseWithinSec", unit = "s"]
        pub fuse_within_sec: f64 = 0.03,
        /// if set, discard transients where the ratemap level is below this
        #[afe = "trm_minValuedB", unit = "dB", kind = ParamKind::Number]
        pub min_value_db: Option<f64> = None,
    }
}

/// The transient map of one ear: onset or offset strength `[frame][channel]` in dB (and,
/// with `trm_minValuedB`, the time-aligned ratemap frames as a second input) in, a 0/1
/// mask of the same shape out.
///
/// Like the AFE, each call detects on the buffered last `ceil(trm_fuseWithinSec·fs)`
/// frames plus the new ones and emits the rows of the new frames only: the output is not
/// chunk-invariant, and frames that arrive while buffer and chunk together are no longer
/// than the buffer are never emitted (the mask of a stream can be shorter than its
/// strength). Unlike the AFE, the `trm_minValuedB` masking is applied in every call
/// (the AFE skips it, with a warning, whenever its stored ratemap is shorter than buffer
/// and chunk together). Each frame is masked once, on arrival, with its own ratemap frame;
/// the AFE masks buffer and chunk on every call, which gives the same values since the
/// buffer keeps masked values, so no ratemap history is needed.
#[derive(Debug, Clone)]
pub struct TransientMap {
    min_strength_db: f64,
    min_spread: u64,
    min_value_db: Option<f64>,
    /// Peak fusion distance in frames, `round(trm_fuseWithinSec/(1/fs))`.
    fuse_frames: usize,
    /// Frames kept between calls, `ceil(trm_fuseWithinSec·fs)`.
    keep: usize,
    channels: usize,
    /// The buffered frames (`buffered` rows), then the new ones, after masking.
    strength: Vec<f64>,
    buffered: usize,
    /// Detection scratch of `[frame][channel]` cells, grown to the largest call.
    scratch: Detection,
}

/// Reusable buffers of one detection.
#[derive(Debug, Clone, Default)]
struct Detection {
    /// Strength with the cells below the minimum set to 0.
    level: Vec<f64>,
    /// Cells marked as transients.
    mask: Vec<bool>,
    /// Component label + 1 of each cell (0: not yet labelled).
    label: Vec<u32>,
    /// Cell count of each component.
    sizes: Vec<u64>,
    /// Cells still to visit while labelling.
    stack: Vec<usize>,
    /// (frame, value) of the peaks of one channel.
    peaks: Vec<(usize, f64)>,
    /// Frames too close to an accepted peak of the channel.
    blocked: Vec<bool>,
}

impl TransientMap {
    /// Builds the map for the strength `input`; `ratemap` describes the ratemap that
    /// `trm_minValuedB` reads (needed exactly when it is set).
    pub fn new(
        params: &TransientMapParams,
        input: &SignalInfo,
        ratemap: Option<&SignalInfo>,
    ) -> Result<(Self, SignalInfo)> {
        let fuse = params.fuse_within_sec;
        if fuse.is_nan() || fuse < 0.0 {
            return Err(Error::invalid(
                TransientMapParams::NAMES.fuse_within_sec,
                fuse,
                "must be at least 0 s",
            ));
        }
        if let Some(min) = params.min_value_db {
            let Some(rm) = ratemap else {
                return Err(Error::invalid(
                    TransientMapParams::NAMES.min_value_db,
                    min,
                    "needs the ratemap as a second input",
                ));
            };
            if rm.channels() != input.channels() {
                return Err(Error::InvalidInput(format!(
                    "the ratemap for trm_minValuedB has {} channels, the strength {}",
                    rm.channels(),
                    input.channels()
                )));
            }
        }
        let fs = input.fs_hz;
        let map = TransientMap {
            min_strength_db: params.min_strength_db,
            min_spread: params.min_spread,
            min_value_db: params.min_value_db,
            fuse_frames: (fuse / (1.0 / fs)).round() as usize,
            keep: (fuse * fs).ceil() as usize,
            channels: input.channels(),
            strength: Vec::new(),
            buffered: 0,
            scratch: Detection::default(),
        };
        let info = SignalInfo {
            kind: SignalKind::BinaryMask,
            ..input.framed(fs)
        };
        Ok((map, info))
    }
}

impl Processor for TransientMap {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let nc = self.channels;
        let new = inputs[0];
        let lb = self.buffered;
        self.strength.truncate(lb * nc);
        self.strength.extend_from_slice(new.as_slice());
        if let (Some(min), Some(ratemap)) = (self.min_value_db, inputs.get(1)) {
            let fresh = self.strength[lb * nc..].chunks_exact_mut(nc);
            for (row, r) in fresh.zip(ratemap.rows()) {
                for (s, v) in row.iter_mut().zip(r) {
                    if 10.0 * v.log10() < min {
                        *s = 0.0;
                    }
                }
            }
        }
        let l = lb + new.frames();
        if l <= self.keep {
            self.buffered = l;
            outputs[0].reset_to(0);
            return;
        }
        self.detect(l);
        let out = outputs[0].resize_to(l - lb);
        for (o, &m) in out.iter_mut().zip(&self.scratch.mask[lb * nc..l * nc]) {
            *o = if m { 1.0 } else { 0.0 };
        }
        self.strength.copy_within((l - self.keep) * nc..l * nc, 0);
        self.strength.truncate(self.keep * nc);
        self.buffered = self.keep;
    }

    fn reset(&mut self) {
        self.strength.clear();
        self.buffered = 0;
    }
}

impl TransientMap {
    /// Marks the transients of the first `l` frames of `strength` in `scratch.mask`.
    fn detect(&mut self, l: usize) {
        let nc = self.channels;
        let d = &mut self.scratch;
        let cells = l * nc;
        d.level.clear();
        d.level.extend(self.strength[..cells].iter().map(|&v| {
            if v < self.min_strength_db {
                0.0
            } else {
                v
            }
        }));
        d.mask.clear();
        d.mask.resize(cells, false);
        for c in 0..nc {
            find_peaks(&d.level, nc, c, &mut d.peaks);
            if self.fuse_frames > 2 {
                // Strongest first (earliest among equals); accept a peak only if no
                // stronger accepted one is closer than the fusion distance.
                d.peaks
                    .sort_unstable_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
                d.blocked.clear();
                d.blocked.resize(l, false);
                for &(t, _) in &d.peaks {
                    if !d.blocked[t] {
                        d.mask[t * nc + c] = true;
                        let near =
                            t.saturating_sub(self.fuse_frames - 1)..(t + self.fuse_frames).min(l);
                        d.blocked[near].fill(true);
                    }
                }
            } else {
                for &(t, _) in &d.peaks {
                    d.mask[t * nc + c] = true;
                }
            }
        }
        d.remove_small_components(l, nc, self.min_spread);
    }
}

/// The peaks over time of channel `c` of the `[frame][nc]` cells `x` (voicebox
/// `findpeaks`, spec 01-P8), as (frame, value) into `peaks`: a plateau (a run of frames
/// with no rise or fall between them, so NaN steps continue it) entered by a rise and
/// left by a fall peaks at its centre, left of centre for an even length. The first and
/// last frames are never peaks.
fn find_peaks(x: &[f64], nc: usize, c: usize, peaks: &mut Vec<(usize, f64)>) {
    peaks.clear();
    let n = x.len() / nc;
    let at = |t: usize| x[t * nc + c];
    // NaN comparisons are false: a step from or to NaN is neither a rise nor a fall.
    let rise = |t: usize| at(t + 1) > at(t);
    let fall = |t: usize| at(t + 1) < at(t);
    let mut t = 1;
    while t < n {
        if !rise(t - 1) {
            t += 1;
            continue;
        }
        let start = t;
        let mut end = t;
        while end + 1 < n && !rise(end) && !fall(end) {
            end += 1;
        }
        if end + 1 < n && fall(end) {
            let k = start + (end - start) / 2;
            peaks.push((k, at(k)));
        }
        t = end + 1;
    }
}

impl Detection {
    /// Clears every 8-connected component of the first `l` rows of `mask` that has fewer
    /// than `min_spread` cells.
    fn remove_small_components(&mut self, l: usize, nc: usize, min_spread: u64) {
        let cells = l * nc;
        self.label.clear();
        self.label.resize(cells, 0);
        self.sizes.clear();
        for seed in 0..cells {
            if !self.mask[seed] || self.label[seed] != 0 {
                continue;
            }
            let id = self.sizes.len() as u32 + 1;
            self.label[seed] = id;
            self.stack.clear();
            self.stack.push(seed);
            let mut size = 0;
            while let Some(cell) = self.stack.pop() {
                size += 1;
                let (t, c) = (cell / nc, cell % nc);
                for tt in t.saturating_sub(1)..(t + 2).min(l) {
                    for cc in c.saturating_sub(1)..(c + 2).min(nc) {
                        let nb = tt * nc + cc;
                        if self.mask[nb] && self.label[nb] == 0 {
                            self.label[nb] = id;
                            self.stack.push(nb);
                        }
                    }
                }
            }
            self.sizes.push(size);
        }
        for (m, &id) in self.mask[..cells].iter_mut().zip(&self.label) {
            if *m && self.sizes[id as usize - 1] < min_spread {
                *m = false;
            }
        }
    }
}

/// The `onsetMap` (`ONSET`) or `offsetMap` request (spec 25): the two differ only in the
/// strength they read.
pub struct MapRequest<const ONSET: bool>;

impl<const ONSET: bool> Descriptor for MapRequest<ONSET> {
    type Params = TransientMapParams;
    const NAME: &'static str = if ONSET { "onsetMap" } else { "offsetMap" };
    const DEPENDENCY: &'static str = if ONSET {
        "onsetStrength"
    } else {
        "offsetStrength"
    };
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str = if ONSET {
        "binary map of salient onsets per frame and channel"
    } else {
        "binary map of salient offsets per frame and channel"
    };
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &TransientMapParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = TransientMap::new(params, &inputs[0], inputs.get(1))?;
        Ok(Built::new(p, vec![out]))
    }

    /// Peak picking and connected components see only the buffer and the chunk.
    fn chunk_invariant(_: &TransientMapParams) -> bool {
        false
    }

    /// The ratemap, beside the strength, when `trm_minValuedB` is set.
    fn extra_inputs(params: &TransientMapParams) -> &'static [&'static str] {
        if params.min_value_db.is_some() {
            &["ratemap"]
        } else {
            &[]
        }
    }
}

/// The registry entry of `onsetMap`.
pub static ONSET_REQUEST: RequestDef = request_def::<MapRequest<true>>();
/// The registry entry of `offsetMap`.
pub static OFFSET_REQUEST: RequestDef = request_def::<MapRequest<false>>();

#[cfg(test)]
mod tests {
    use super::*;

    fn strength_info(channels: usize) -> SignalInfo {
        SignalInfo::time_frequency(
            44100.0,
            (0..channels).map(|c| 100.0 * (c + 1) as f64).collect(),
        )
        .framed(100.0)
    }

    /// The map with default parameters over `channels` channels.
    fn default_map(channels: usize) -> TransientMap {
        TransientMap::new(
            &TransientMapParams::default(),
            &strength_info(channels),
            None,
        )
        .expect("valid")
        .0
    }

    fn peaks_of(x: &[f64]) -> Vec<usize> {
        let mut p = Vec::new();
        find_peaks(x, 1, 0, &mut p);
        p.iter().map(|&(t, _)| t).collect()
    }

    fn run(map: &mut TransientMap, inputs: &[&Block]) -> Block {
        let mut out = vec![Block::new(map.channels)];
        map.process(inputs, &mut out);
        out.remove(0)
    }

    /// `frames` frames of `nc` channels, 0 except `value` at the given (frame, channel).
    fn cells(frames: usize, nc: usize, on: &[(usize, usize)], value: f64) -> Block {
        let mut data = vec![0.0; frames * nc];
        for &(t, c) in on {
            data[t * nc + c] = value;
        }
        Block::from_vec(data, nc)
    }

    fn marked(b: &Block) -> Vec<(usize, usize)> {
        let nc = b.width();
        let v = b.as_slice();
        (0..v.len())
            .filter(|&i| v[i] == 1.0)
            .map(|i| (i / nc, i % nc))
            .collect()
    }

    #[test]
    fn bad_parameters_name_themselves() {
        let info = strength_info(3);
        let p = TransientMapParams {
            fuse_within_sec: -0.01,
            ..Default::default()
        };
        let e = TransientMap::new(&p, &info, None).unwrap_err().to_string();
        assert!(e.contains("trm_fuseWithinSec"), "{e}");
        let p = TransientMapParams {
            min_value_db: Some(-40.0),
            ..Default::default()
        };
        let e = TransientMap::new(&p, &info, None).unwrap_err().to_string();
        assert!(e.contains("trm_minValuedB") && e.contains("ratemap"), "{e}");
        let e = TransientMap::new(&p, &info, Some(&strength_info(2)))
            .unwrap_err()
            .to_string();
        assert!(e.contains("channels"), "{e}");
        let (_, out) = TransientMap::new(&p, &info, Some(&info)).expect("valid");
        assert_eq!((out.kind, out.fs_hz), (SignalKind::BinaryMask, 100.0));
    }

    #[test]
    fn peaks_are_plateau_centres_never_end_points() {
        assert_eq!(peaks_of(&[5.0, 1.0, 2.0, 1.0, 3.0]), [2]);
        assert_eq!(peaks_of(&[0.0, 2.0, 2.0, 2.0, 1.0]), [2]);
        assert_eq!(peaks_of(&[0.0, 2.0, 2.0, 2.0, 2.0, 1.0]), [2]);
        assert_eq!(peaks_of(&[0.0, 2.0, 2.0, 3.0, 1.0]), [3]);
        assert_eq!(peaks_of(&[0.0, 1.0, 2.0, 2.0]), Vec::<usize>::new());
        assert_eq!(peaks_of(&[0.0, 1.0, f64::NAN, 1.0, 0.0]), [2]);
        assert_eq!(peaks_of(&[1.0; 4]), Vec::<usize>::new());
    }

    #[test]
    fn close_peaks_fuse_to_the_strongest_and_small_components_vanish() {
        // One channel: peaks at frames 2 (4 dB), 4 (6 dB), 7 (5 dB), 9 (2 dB: too weak).
        // Fusion over 3 frames keeps 4 and 7; single cells are components of one.
        let x = [0.0, 1.0, 4.0, 1.0, 6.0, 0.0, 0.0, 5.0, 0.0, 2.0, 0.0];
        let p = TransientMapParams {
            min_spread: 1,
            ..Default::default()
        };
        let (mut map, _) = TransientMap::new(&p, &strength_info(1), None).expect("valid");
        let out = run(&mut map, &[&Block::from_vec(x.to_vec(), 1)]);
        assert_eq!(marked(&out), [(4, 0), (7, 0)]);
        // A weaker peak exactly the fusion distance before the stronger one stays too.
        map.reset();
        let before = [0.0, 0.0, 0.0, 4.0, 0.0, 0.0, 6.0, 0.0, 0.0];
        let out = run(&mut map, &[&Block::from_vec(before.to_vec(), 1)]);
        assert_eq!(marked(&out), [(3, 0), (6, 0)]);
        let mut map = default_map(1);
        let out = run(&mut map, &[&Block::from_vec(x.to_vec(), 1)]);
        assert!(marked(&out).is_empty());
    }

    #[test]
    fn diagonal_chains_are_connected() {
        // Five peaks on a diagonal: one 8-connected component of five cells, kept; four
        // peaks in a row are removed.
        let nc = 6;
        let diagonal: Vec<(usize, usize)> = (0..5).map(|k| (k + 1, k)).collect();
        let mut map = default_map(nc);
        let out = run(&mut map, &[&cells(8, nc, &diagonal, 10.0)]);
        assert_eq!(marked(&out), diagonal);
        map.reset();
        let out = run(&mut map, &[&cells(8, nc, &diagonal[..4], 10.0)]);
        assert!(marked(&out).is_empty());
    }

    #[test]
    fn buffer_only_calls_are_never_emitted_and_buffered_rows_not_repeated() {
        let nc = 5;
        let column: Vec<(usize, usize)> = (0..nc).map(|c| (1, c)).collect();
        let mut map = default_map(nc);
        // Three frames fit the buffer (ceil(0.03·100) = 3): nothing is emitted, ever.
        assert_eq!(run(&mut map, &[&cells(3, nc, &column, 10.0)]).frames(), 0);
        // The next call detects on buffer + chunk and emits only the chunk's rows; the
        // transient at frame 1 of the buffer is found but lies in the buffer.
        let out = run(&mut map, &[&cells(4, nc, &[], 0.0)]);
        assert_eq!(out.frames(), 4);
        assert!(marked(&out).is_empty());
        // A transient in the last frame of a chunk has no following fall yet: missed,
        // and later only seen inside the buffer.
        let out = run(
            &mut map,
            &[&cells(
                4,
                nc,
                &column.iter().map(|&(_, c)| (3, c)).collect::<Vec<_>>(),
                10.0,
            )],
        );
        assert!(marked(&out).is_empty());
        assert!(marked(&run(&mut map, &[&cells(2, nc, &[], 0.0)])).is_empty());
        // The same frames in one call: the transient is kept.
        map.reset();
        let mut all = cells(7, nc, &[], 0.0);
        all.extend_from(&cells(
            4,
            nc,
            &column.iter().map(|&(_, c)| (3, c)).collect::<Vec<_>>(),
            10.0,
        ));
        all.extend_from(&cells(2, nc, &[], 0.0));
        let out = run(&mut map, &[&all]);
        assert_eq!(
            marked(&out),
            column.iter().map(|&(_, c)| (10, c)).collect::<Vec<_>>()
        );
    }

    #[test]
    fn min_value_masks_cells_where_the_ratemap_is_quiet() {
        // A column-wide onset at frame 2 (of 0..10, two calls of 5), channel 4 quiet in
        // the ratemap (1e-6 → −60 dB < −40 dB): its cell is zeroed before detection and
        // the remaining four cells are too few for the default spread of 5 — unless the
        // spread is 4.
        let nc = 5;
        let column: Vec<(usize, usize)> = (0..nc).map(|c| (2, c)).collect();
        let strength = cells(10, nc, &column, 10.0);
        let mut rm = vec![1.0; 10 * nc];
        rm[2 * nc + 4] = 1e-6;
        let ratemap = Block::from_vec(rm, nc);
        let halves = |b: &Block, k: usize| {
            Block::from_vec(b.as_slice()[k * 5 * nc..(k + 1) * 5 * nc].to_vec(), nc)
        };
        for (spread, expect) in [(5, vec![]), (4, vec![(2, 0), (2, 1), (2, 2), (2, 3)])] {
            let p = TransientMapParams {
                min_value_db: Some(-40.0),
                min_spread: spread,
                ..Default::default()
            };
            let info = strength_info(nc);
            let (mut map, _) = TransientMap::new(&p, &info, Some(&info)).expect("valid");
            let first = run(&mut map, &[&halves(&strength, 0), &halves(&ratemap, 0)]);
            let second = run(&mut map, &[&halves(&strength, 1), &halves(&ratemap, 1)]);
            assert_eq!(first.frames() + second.frames(), 10);
            assert_eq!(marked(&first), expect);
            assert!(marked(&second).is_empty());
        }
        // Without the threshold all five cells form a transient.
        let mut map = default_map(nc);
        assert_eq!(marked(&run(&mut map, &[&strength])), column);
    }

    #[test]
    fn strength_at_the_threshold_counts() {
        let nc = 5;
        let column: Vec<(usize, usize)> = (0..nc).map(|c| (2, c)).collect();
        let mut map = default_map(nc);
        assert_eq!(
            marked(&run(&mut map, &[&cells(6, nc, &column, 3.0)])),
            column
        );
        map.reset();
        let below = 3.0 - 1e-12;
        assert!(marked(&run(&mut map, &[&cells(6, nc, &column, below)])).is_empty());
    }
    /// `frames` rows of `nc` channels, each row one value across the channels.
    fn rows(values: &[f64], nc: usize) -> Block {
        Block::from_vec(values.iter().flat_map(|&v| vec![v; nc]).collect(), nc)
    }

    #[test]
    fn a_peak_at_a_chunk_start_rises_from_the_buffered_rows() {
        // Only the last three frames of the first call (20, 20, 5) show the rise into the
        // 10 that starts the second call; its earlier frames are all 20.
        let nc = 5;
        let column: Vec<(usize, usize)> = (0..nc).map(|c| (0, c)).collect();
        let mut map = default_map(nc);
        let first = run(&mut map, &[&rows(&[20.0, 20.0, 20.0, 20.0, 20.0, 5.0], nc)]);
        assert!(marked(&first).is_empty());
        let second = run(&mut map, &[&rows(&[10.0, 0.0, 0.0, 0.0], nc)]);
        assert_eq!(second.frames(), 4);
        assert_eq!(marked(&second), column);
    }

    #[test]
    fn min_value_masks_the_new_rows_of_a_later_call_and_keeps_its_threshold() {
        // A rise from the buffered 5s into the 10 that starts the second call, with the
        // ratemap of channel 4 at that frame at or below −20 dB. At −20 dB exactly the
        // cell stays. (Masking a buffered frame instead would leave the peak.)
        assert_eq!(10.0 * 0.01f64.log10(), -20.0);
        let nc = 5;
        let p = TransientMapParams {
            min_value_db: Some(-20.0),
            ..Default::default()
        };
        let info = strength_info(nc);
        for (level, kept) in [(0.01, nc), (0.0099, 0)] {
            let (mut map, _) = TransientMap::new(&p, &info, Some(&info)).expect("valid");
            let loud = rows(&[1.0; 6], nc);
            run(
                &mut map,
                &[&rows(&[20.0, 20.0, 20.0, 5.0, 5.0, 5.0], nc), &loud],
            );
            let mut rm = vec![1.0; 4 * nc];
            rm[4] = level;
            let ratemap = Block::from_vec(rm, nc);
            let out = run(&mut map, &[&rows(&[10.0, 0.0, 0.0, 0.0], nc), &ratemap]);
            assert_eq!(marked(&out).len(), kept, "ratemap level {level}");
        }
    }

    #[test]
    fn reset_forgets_the_buffered_frames() {
        let nc = 2;
        let mut map = default_map(nc);
        assert_eq!(run(&mut map, &[&rows(&[1.0, 2.0], nc)]).frames(), 0);
        map.reset();
        assert_eq!(run(&mut map, &[&rows(&[1.0, 2.0], nc)]).frames(), 0);
        assert_eq!(run(&mut map, &[&rows(&[1.0, 2.0], nc)]).frames(), 2);
    }

    #[test]
    fn without_fusion_every_peak_of_every_channel_is_marked() {
        // A fusion distance of one frame (at most two is no fusion): peaks two frames
        // apart in five channels are two components of five cells.
        let nc = 5;
        let p = TransientMapParams {
            fuse_within_sec: 0.01,
            ..Default::default()
        };
        let (mut map, _) = TransientMap::new(&p, &strength_info(nc), None).expect("valid");
        let out = run(&mut map, &[&rows(&[0.0, 0.0, 10.0, 0.0, 9.0, 0.0], nc)]);
        let want: Vec<(usize, usize)> = [2, 4]
            .iter()
            .flat_map(|&t| (0..nc).map(move |c| (t, c)))
            .collect();
        assert_eq!(marked(&out), want);
    }
}
