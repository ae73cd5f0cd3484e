//! `spectralFeatures`: frame-wise scalar descriptors of the ratemap across its auditory
//! channels (centroid, crest, ..., variation; spec 26-spectralFeatures).

use afe_core::descriptor::{request_def, Built, Descriptor, Ears, RequestDef};
use afe_core::{Block, Error, Params, Processor, Result, SignalInfo};

afe_core::choices! {
    /// One spectral feature, or `all` of them (AFE names).
    pub enum SpectralFeature {
        /// Every feature below, in this order.
        All = "all",
        /// Centre of gravity of the channel CFs, over the highest CF.
        Centroid = "centroid",
        /// Peak over mean.
        Crest = "crest",
        /// Spread of the CFs around the centroid, over the highest CF.
        Spread = "spread",
        /// Entropy of the normalised frame, over `ln(channels)`.
        Entropy = "entropy",
        /// Share of the frame above `sf_brCF`.
        Brightness = "brightness",
        /// High-frequency content: mean of CF² weighted by the frame, in Hz².
        Hfc = "hfc",
        /// Mean decrease from the first channel, weighted by 1/k.
        Decrease = "decrease",
        /// Geometric over arithmetic mean.
        Flatness = "flatness",
        /// RMS change of the dB frame from the previous frame.
        Flux = "flux",
        /// Excess kurtosis across channels.
        Kurtosis = "kurtosis",
        /// Skewness across channels.
        Skewness = "skewness",
        /// RMS dB step between adjacent channels.
        Irregularity = "irregularity",
        /// CF below which `sf_roPerc` of the frame lies, over the highest CF.
        Rolloff = "rolloff",
        /// One minus the cosine similarity with the previous frame.
        Variation = "variation",
    }
}

/// The features `all` stands for, in the AFE's output order.
const EVERY_FEATURE: [SpectralFeature; 14] = [
    SpectralFeature::Centroid,
    SpectralFeature::Crest,
    SpectralFeature::Spread,
    SpectralFeature::Entropy,
    SpectralFeature::Brightness,
    SpectralFeature::Hfc,
    SpectralFeature::Decrease,
    SpectralFeature::Flatness,
    SpectralFeature::Flux,
    SpectralFeature::Kurtosis,
    SpectralFeature::Skewness,
    SpectralFeature::Irregularity,
    SpectralFeature::Rolloff,
    SpectralFeature::Variation,
];

afe_core::params! {
    /// Parameters of the spectral features, under their AFE names.
    pub struct SpectralFeaturesParams / SpectralFeaturesNames {
        /// features to compute, in output order, or 'all'
        #[afe = "sf_requests"]
        pub requests: Vec<SpectralFeature> = vec![SpectralFeature::All],
        /// cut-off frequency of the brightness
        #[afe = "sf_brCF", unit = "Hz"]
        pub brightness_cf_hz: f64 = 1500.0,
        /// fraction of the frame's total below the rolloff frequency
        #[afe = "sf_roPerc"]
        pub rolloff_fraction: f64 = 0.8,
    }
}

impl SpectralFeaturesParams {
    /// The requested features with `all` expanded, as the AFE's verification does.
    pub fn features(&self) -> Result<Vec<SpectralFeature>> {
        let bad = |reason: &str| {
            Error::invalid(
                SpectralFeaturesParams::NAMES.requests,
                format!(
                    "[{}]",
                    self.requests
                        .iter()
                        .map(|f| format!("'{}'", f.name()))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                reason,
            )
        };
        match self.requests.as_slice() {
            [] => Err(bad("name at least one feature, or 'all'")),
            [SpectralFeature::All] => Ok(EVERY_FEATURE.to_vec()),
            r if r.contains(&SpectralFeature::All) => {
                Err(bad("'all' cannot be combined with feature names"))
            }
            r => Ok(r.to_vec()),
        }
    }
}

/// Guard of the divisions (`ε` of the spec).
const EPS: f64 = 1e-15;
/// Added to each channel of the rolloff's cumulative sum, which makes it increasing.
const EPS_ROLLOFF: f64 = 1e-10;

/// The spectral features of one ear: ratemap `[frame][channel]` in, `[frame][feature]`
/// out.
#[derive(Debug, Clone)]
pub struct SpectralFeatures {
    features: Vec<SpectralFeature>,
    cf_hz: Vec<f64>,
    /// `cf²` of each channel in Hz².
    cf2: Vec<f64>,
    /// Whether each channel's CF is above `sf_brCF`.
    bright: Vec<bool>,
    rolloff_fraction: f64,
    /// Previous frame, linear (variation) and in dB (flux); empty before the first frame.
    prev: Vec<f64>,
    prev_db: Vec<f64>,
    /// The current frame in dB, and the rolloff's cumulative sum.
    db: Vec<f64>,
    cumsum: Vec<f64>,
}

impl SpectralFeatures {
    /// Builds the spectral features for the ratemap `input`.
    pub fn new(params: &SpectralFeaturesParams, input: &SignalInfo) -> Result<(Self, SignalInfo)> {
        let features = params.features()?;
        let f = params.rolloff_fraction;
        if !(0.0..=1.0).contains(&f) {
            return Err(Error::invalid(
                SpectralFeaturesParams::NAMES.rolloff_fraction,
                f,
                "must be a fraction between 0 and 1",
            ));
        }
        if !params.brightness_cf_hz.is_finite() {
            return Err(Error::invalid(
                SpectralFeaturesParams::NAMES.brightness_cf_hz,
                params.brightness_cf_hz,
                "must be a finite frequency in Hz",
            ));
        }
        let k = input.channels();
        if k < 2 {
            return Err(Error::InvalidInput(format!(
                "spectral features need at least 2 frequency channels, the ratemap has {k}"
            )));
        }
        let cf = input.cf_hz().to_vec();
        let names = features.iter().map(|f| f.name().to_string()).collect();
        let sf = SpectralFeatures {
            features,
            cf2: cf.iter().map(|c| c * c).collect(),
            bright: cf.iter().map(|&c| c > params.brightness_cf_hz).collect(),
            cf_hz: cf,
            rolloff_fraction: f,
            prev: Vec::with_capacity(k),
            prev_db: Vec::with_capacity(k),
            db: vec![0.0; k],
            cumsum: vec![0.0; k],
        };
        let info = SignalInfo {
            window_s: input.window_s,
            ..SignalInfo::feature(input.fs_hz, input.audio_fs_hz, names)
        }
        .with_unit(Self::OUTPUT_UNIT)
        .nan_where(
            "with ihc_method 'none' and rm_scaling 'magnitude' only: the ratemap is then signed \
             and the logarithms of its negative values are NaN",
        );
        Ok((sf, info))
    }

    /// The features of frame `x` into `out` (previous frames already in `prev*`).
    fn frame(&mut self, x: &[f64], out: &mut [f64]) {
        let k = x.len() as f64;
        let cf_max = self.cf_hz[self.cf_hz.len() - 1];
        let total: f64 = x.iter().sum();
        let mean = total / k;
        let weighted: f64 = self.cf_hz.iter().zip(x).map(|(c, v)| c * v).sum();
        let centroid = weighted / (total + EPS);
        for (d, v) in self.db.iter_mut().zip(x) {
            *d = 10.0 * (v + EPS).log10();
        }
        for (feature, o) in self.features.iter().zip(out.iter_mut()) {
            *o = match feature {
                SpectralFeature::Centroid => centroid / cf_max,
                SpectralFeature::Crest => x.iter().fold(f64::NAN, |m, &v| m.max(v)) / (mean + EPS),
                SpectralFeature::Spread => {
                    let s: f64 = self
                        .cf_hz
                        .iter()
                        .zip(x)
                        .map(|(c, v)| (c - centroid) * (c - centroid) * v)
                        .sum();
                    (s / (total + EPS)).sqrt() / cf_max
                }
                SpectralFeature::Entropy => {
                    let s: f64 = x
                        .iter()
                        .map(|v| {
                            let p = v / (total + EPS);
                            p * (p + EPS).ln()
                        })
                        .sum();
                    -s / k.ln()
                }
                SpectralFeature::Brightness => {
                    let s: f64 = x
                        .iter()
                        .zip(&self.bright)
                        .filter(|(_, &b)| b)
                        .map(|(v, _)| v)
                        .sum();
                    s / (total + EPS)
                }
                SpectralFeature::Hfc => {
                    let s: f64 = self.cf2.iter().zip(x).map(|(c2, v)| c2 * v).sum();
                    s / (total + EPS)
                }
                SpectralFeature::Decrease => {
                    let s: f64 = x[1..]
                        .iter()
                        .enumerate()
                        .map(|(i, v)| (v - x[0]) / (i + 1) as f64)
                        .sum();
                    let rest: f64 = x[1..].iter().sum();
                    s / (rest + EPS)
                }
                SpectralFeature::Flatness => {
                    let logs: f64 = x.iter().map(|v| v.ln()).sum();
                    (logs / k).exp() / (mean + EPS)
                }
                SpectralFeature::Flux => {
                    let prev = if self.prev_db.is_empty() {
                        &self.db
                    } else {
                        &self.prev_db
                    };
                    let s: f64 = self
                        .db
                        .iter()
                        .zip(prev)
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum();
                    (s / k).sqrt()
                }
                SpectralFeature::Kurtosis | SpectralFeature::Skewness => {
                    let mu = x.iter().map(|v| v.abs()).sum::<f64>() / k;
                    let var: f64 = x.iter().map(|v| (v.abs() - mu) * (v.abs() - mu)).sum();
                    let sigma = (var / (k - 1.0)).sqrt() + EPS;
                    let kurtosis = *feature == SpectralFeature::Kurtosis;
                    let power = if kurtosis { 4 } else { 3 };
                    let scale = sigma.powi(power);
                    let s: f64 = x.iter().map(|v| (v - mu).powi(power) / scale).sum();
                    let m = s / k;
                    if kurtosis {
                        m - 3.0
                    } else {
                        m
                    }
                }
                SpectralFeature::Irregularity => {
                    let s: f64 = self
                        .db
                        .windows(2)
                        .map(|w| (w[1] - w[0]) * (w[1] - w[0]))
                        .sum();
                    (s / (k - 1.0)).sqrt()
                }
                SpectralFeature::Rolloff => {
                    let target = self.rolloff_fraction * total;
                    rolloff(x, target, &self.cf_hz, &mut self.cumsum) / cf_max
                }
                SpectralFeature::Variation => {
                    let prev = if self.prev.is_empty() { x } else { &self.prev };
                    let cross: f64 = x.iter().zip(prev).map(|(a, b)| a * b).sum();
                    let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
                    1.0 - cross / (norm(x) * norm(prev) + EPS)
                }
                SpectralFeature::All => unreachable!("'all' is expanded in the constructor"),
            };
        }
        self.prev.clear();
        self.prev.extend_from_slice(x);
        self.prev_db.clear();
        self.prev_db.extend_from_slice(&self.db);
    }
}

/// The frequency in Hz at which the cumulative sum of `x` (each channel plus
/// [`EPS_ROLLOFF`], written into `cumsum`) reaches `target`, linear between the channel
/// CFs `cf_hz` and extrapolated from the first or last segment; 0 for a target ≤ 0.
fn rolloff(x: &[f64], target: f64, cf_hz: &[f64], cumsum: &mut [f64]) -> f64 {
    if target.is_nan() || target <= 0.0 {
        return 0.0;
    }
    let mut acc = 0.0;
    for (c, v) in cumsum.iter_mut().zip(x) {
        acc += v + EPS_ROLLOFF;
        *c = acc;
    }
    let n = cumsum.len();
    // The segment [i, i+1] holding the target, or the first/last for extrapolation.
    let i = cumsum[1..n - 1].partition_point(|&v| v < target);
    let (x0, x1) = (cumsum[i], cumsum[i + 1]);
    let (y0, y1) = (cf_hz[i], cf_hz[i + 1]);
    y0 + (target - x0) * (y1 - y0) / (x1 - x0)
}

impl Processor for SpectralFeatures {
    fn process(&mut self, inputs: &[&Block], outputs: &mut [Block]) {
        let x = inputs[0];
        let nf = self.features.len();
        let out = outputs[0].resize_to(x.frames());
        for (row, o) in x.rows().zip(out.chunks_exact_mut(nf)) {
            self.frame(row, o);
        }
    }

    fn reset(&mut self) {
        self.prev.clear();
        self.prev_db.clear();
    }
}

impl Descriptor for SpectralFeatures {
    type Params = SpectralFeaturesParams;
    const NAME: &'static str = "spectralFeatures";
    const DEPENDENCY: &'static str = "ratemap";
    const EARS: Ears = Ears::PerEar;
    const DESCRIPTION: &'static str = "spectral shape descriptors of each ratemap frame";
    const OUTPUT_UNIT: &'static str = "";

    fn build(params: &SpectralFeaturesParams, inputs: &[SignalInfo]) -> Result<Built> {
        let (p, out) = SpectralFeatures::new(params, &inputs[0])?;
        Ok(Built::new(p, vec![out]))
    }

    /// `sf_requests = 'all'` expanded, as the AFE verifies it.
    fn canonical(params: &SpectralFeaturesParams) -> Result<afe_core::ParamMap> {
        let mut p = params.clone();
        p.requests = p.features()?;
        Ok(p.to_map())
    }
}

/// The registry entry of `spectralFeatures`.
pub static REQUEST: RequestDef = request_def::<SpectralFeatures>();

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ratemap_info(channels: usize) -> SignalInfo {
        let cf = (0..channels).map(|c| 250.0 * (c + 1) as f64).collect();
        SignalInfo::time_frequency(16000.0, cf).framed(100.0)
    }

    fn run(sf: &mut SpectralFeatures, data: &[f64], nc: usize) -> Vec<f64> {
        let mut out = vec![Block::new(sf.features.len())];
        sf.process(&[&Block::from_vec(data.to_vec(), nc)], &mut out);
        out[0].as_slice().to_vec()
    }

    #[test]
    fn all_expands_in_the_afe_order() {
        let (_, info) = SpectralFeatures::new(&SpectralFeaturesParams::default(), &ratemap_info(4))
            .expect("valid");
        assert_eq!(
            info.features(),
            [
                "centroid",
                "crest",
                "spread",
                "entropy",
                "brightness",
                "hfc",
                "decrease",
                "flatness",
                "flux",
                "kurtosis",
                "skewness",
                "irregularity",
                "rolloff",
                "variation"
            ]
        );
        assert_eq!((info.fs_hz, info.audio_fs_hz), (100.0, 16000.0));
    }

    #[test]
    fn bad_parameters_name_themselves() {
        let info = ratemap_info(4);
        let bad = [
            SpectralFeaturesParams {
                requests: vec![SpectralFeature::All, SpectralFeature::Crest],
                ..Default::default()
            },
            SpectralFeaturesParams {
                requests: vec![],
                ..Default::default()
            },
            SpectralFeaturesParams {
                rolloff_fraction: 1.5,
                ..Default::default()
            },
            SpectralFeaturesParams {
                brightness_cf_hz: f64::INFINITY,
                ..Default::default()
            },
        ];
        for (p, name) in bad
            .iter()
            .zip(["sf_requests", "sf_requests", "sf_roPerc", "sf_brCF"])
        {
            let e = SpectralFeatures::new(p, &info).unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
        let map = afe_core::ParamMap::from([("sf_requests".into(), serde_json::json!(["crust"]))]);
        let e = SpectralFeaturesParams::from_map(&map)
            .unwrap_err()
            .to_string();
        assert!(e.contains("sf_requests") && e.contains("'centroid'"), "{e}");
    }

    #[test]
    fn features_of_known_frames() {
        // CFs 250, 500, 750, 1000 Hz; brightness above 600 Hz.
        let p = SpectralFeaturesParams {
            brightness_cf_hz: 600.0,
            rolloff_fraction: 0.5,
            ..Default::default()
        };
        let (mut sf, _) = SpectralFeatures::new(&p, &ratemap_info(4)).expect("valid");
        let x = [1.0, 1.0, 1.0, 1.0];
        let got = run(&mut sf, &x, 4);
        let close = |a: f64, b: f64| (a - b).abs() < 1e-9 * b.abs().max(1.0);
        let expect = [
            ("centroid", 625.0 / 1000.0),
            ("crest", 1.0),
            ("spread", (62500.0f64 * 5.0 / 4.0).sqrt() / 1000.0),
            ("entropy", 1.0),
            ("brightness", 0.5),
            ("hfc", (62500.0 + 250000.0 + 562500.0 + 1e6) / 4.0),
            ("decrease", 0.0),
            ("flatness", 1.0),
            ("flux", 0.0),
            ("kurtosis", -3.0),
            ("skewness", 0.0),
            ("irregularity", 0.0),
            // Half of the total (2) is reached at the second channel (cumsum 2 + 2e-10).
            ("rolloff", 0.5),
            ("variation", 0.0),
        ];
        for (i, (name, v)) in expect.iter().enumerate() {
            assert!(close(got[i], *v), "{name}: {} vs {v}", got[i]);
        }
        // The next frame doubles the level: flux 10·log10(2) dB, variation 0.
        let got = run(&mut sf, &[2.0; 4], 4);
        assert!(close(got[8], 10.0 * 2f64.log10()), "flux {}", got[8]);
        assert!(got[13].abs() < 1e-12);
    }

    /// Every feature of uneven frames (one with a zero channel) against its definition
    /// in spec 26, written out with plain loops over six unevenly spaced CFs; also at
    /// 1e-15 and 3e-8 times the level, where the guards `ε` of the sums and of `σ`
    /// (near 1e-15) and of the norms' product (near 1e-15 at 3e-8) change the values.
    #[test]
    fn every_feature_matches_its_definition_on_uneven_frames() {
        let cf = [200.0, 350.0, 600.0, 1100.0, 1900.0, 3300.0];
        let info = SignalInfo::time_frequency(16000.0, cf.to_vec()).framed(100.0);
        let p = SpectralFeaturesParams {
            brightness_cf_hz: 1100.0,
            rolloff_fraction: 0.7,
            ..Default::default()
        };
        let (mut sf, _) = SpectralFeatures::new(&p, &info).expect("valid");
        let uneven = [
            [0.3, 2.0, 0.7, 5.0, 0.1, 1.2],
            [1.5, 0.2, 0.0, 0.9, 3.0, 0.4],
            [0.05, 0.6, 2.5, 0.3, 0.8, 7.0],
        ];
        let mut frames: Vec<[f64; 6]> = [1.0, 1e-15, 3e-8]
            .iter()
            .flat_map(|&scale| uneven.map(|x| x.map(|v| v * scale)))
            .collect();
        // Silence (rolloff 0, not an extrapolation), and a level of 1e4 that varies by
        // 1e-3, where Σ(x − μ)² and Σx² − Kμ² differ by cancellation.
        frames.push([0.0; 6]);
        frames.push(uneven[0].map(|v| 1e4 + 1e-3 * v));
        let got = run(&mut sf, frames.as_flattened(), 6);
        let eps = 1e-15;
        let n = 6.0;
        let db = |x: &[f64; 6]| x.map(|v| 10.0 * (v + eps).log10());
        for (f, x) in frames.iter().enumerate() {
            let prev = &frames[f.saturating_sub(1)];
            let sum: f64 = x.iter().sum();
            let mean = sum / n;
            let mut mu = 0.0;
            let (mut cross, mut norm, mut norm_prev) = (0.0, 0.0, 0.0);
            for k in 0..6 {
                mu += cf[k] * x[k];
                cross += x[k] * prev[k];
                norm += x[k] * x[k];
                norm_prev += prev[k] * prev[k];
            }
            mu /= sum + eps;
            let (mut spread, mut entropy, mut bright, mut hfc, mut logs) =
                (0.0, 0.0, 0.0, 0.0, 0.0);
            let (mut flux, mut dev2, mut dev3, mut dev4) = (0.0, 0.0, 0.0, 0.0);
            let (p_db, prev_db) = (db(x), db(prev));
            for k in 0..6 {
                spread += (cf[k] - mu).powi(2) * x[k];
                let pk = x[k] / (sum + eps);
                entropy -= pk * (pk + eps).ln();
                if cf[k] > 1100.0 {
                    bright += x[k];
                }
                hfc += cf[k] * cf[k] * x[k];
                logs += x[k].ln();
                flux += (p_db[k] - prev_db[k]).powi(2);
                dev2 += (x[k] - mean).powi(2);
            }
            let sigma = (dev2 / (n - 1.0)).sqrt() + eps;
            for v in x {
                dev3 += ((v - mean) / sigma).powi(3);
                dev4 += ((v - mean) / sigma).powi(4);
            }
            let (mut decrease, mut rest) = (0.0, 0.0);
            for k in 1..6 {
                decrease += (x[k] - x[0]) / k as f64;
                rest += x[k];
            }
            let irregularity: f64 = (0..5).map(|k| (p_db[k + 1] - p_db[k]).powi(2)).sum();
            // interp1 on the cumulative sums, extrapolating the first segment below C_0.
            let target = 0.7 * sum;
            let mut c = [0.0; 6];
            let mut acc = 0.0;
            for k in 0..6 {
                acc += x[k] + 1e-10;
                c[k] = acc;
            }
            let seg = (0..5).find(|&k| target <= c[k + 1]).expect("inside");
            let rolloff = if target > 0.0 {
                cf[seg] + (target - c[seg]) * (cf[seg + 1] - cf[seg]) / (c[seg + 1] - c[seg])
            } else {
                0.0
            };
            let max = x.iter().copied().fold(0.0, f64::max);
            let want = [
                mu / 3300.0,
                max / (mean + eps),
                (spread / (sum + eps)).sqrt() / 3300.0,
                entropy / n.ln(),
                bright / (sum + eps),
                hfc / (sum + eps),
                decrease / (rest + eps),
                (logs / n).exp() / (mean + eps),
                (flux / n).sqrt(),
                dev4 / n - 3.0,
                dev3 / n,
                (irregularity / (n - 1.0)).sqrt(),
                rolloff / 3300.0,
                1.0 - cross / (norm.sqrt() * norm_prev.sqrt() + eps),
            ];
            for (i, w) in want.iter().enumerate() {
                let g = got[f * 14 + i];
                assert!(
                    (g - w).abs() <= 1e-12 * w.abs().max(1e-6),
                    "frame {f}, {}: {g} vs {w}",
                    EVERY_FEATURE[i].name()
                );
            }
        }
        // The second frame has a zero channel: no flatness.
        assert_eq!(got[14 + 7], 0.0);
    }

    /// `'all'` and the fourteen names spelt out are one node: both canonical maps list
    /// the names.
    #[test]
    fn all_and_its_names_share_a_node() {
        let all = SpectralFeatures::canonical(&SpectralFeaturesParams::default()).expect("valid");
        let spelt = SpectralFeaturesParams {
            requests: EVERY_FEATURE.to_vec(),
            ..Default::default()
        };
        assert_eq!(all, spelt.to_map());
        assert_eq!(all["sf_requests"][13], "variation");
        assert_eq!(all["sf_roPerc"], 0.8);
    }

    #[test]
    fn requested_features_come_in_the_given_order_and_reset_clears_the_history() {
        let p = SpectralFeaturesParams {
            requests: vec![SpectralFeature::Variation, SpectralFeature::Flux],
            ..Default::default()
        };
        let (mut sf, info) = SpectralFeatures::new(&p, &ratemap_info(3)).expect("valid");
        assert_eq!(info.features(), ["variation", "flux"]);
        run(&mut sf, &[1.0, 5.0, 2.0], 3);
        sf.reset();
        // After a reset the first frame is compared with itself again.
        let got = run(&mut sf, &[4.0, 0.5, 3.0], 3);
        assert!(got[0].abs() < 1e-15 && got[1] == 0.0, "{got:?}");
    }

    #[test]
    fn silent_frame() {
        let (mut sf, _) =
            SpectralFeatures::new(&SpectralFeaturesParams::default(), &ratemap_info(4))
                .expect("valid");
        let got = run(&mut sf, &[0.0; 4], 4);
        let expect = [
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -3.0, 0.0, 0.0, 0.0, 1.0,
        ];
        assert_eq!(got, expect);
    }

    #[test]
    fn rolloff_extrapolates_below_the_first_channel() {
        let p = SpectralFeaturesParams {
            requests: vec![SpectralFeature::Rolloff],
            rolloff_fraction: 0.1,
            ..Default::default()
        };
        let (mut sf, _) = SpectralFeatures::new(&p, &ratemap_info(4)).expect("valid");
        // Target 0.4 below the first cumulative value 1: on the line through (1, 250)
        // and (2, 500), at 0.4 → 100 Hz (up to the 1e-10 offsets).
        let got = run(&mut sf, &[1.0; 4], 4);
        assert!((got[0] - 100.0 / 1000.0).abs() < 1e-9, "{}", got[0]);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

        /// Random chunkings of a random ratemap give the one-call output bit for bit.
        #[test]
        fn any_chunking_is_bit_identical(
            data in prop::collection::vec(prop_oneof![Just(0.0), 1e-6f64..10.0], 5 * 30),
            cuts in prop::collection::vec(0usize..=30, 0..8),
        ) {
            let nc = 5;
            let make = || {
                SpectralFeatures::new(&SpectralFeaturesParams::default(), &ratemap_info(nc))
                    .expect("valid")
                    .0
            };
            let whole = run(&mut make(), &data, nc);
            let mut sf = make();
            let mut bounds = cuts.clone();
            bounds.extend([0, 30]);
            bounds.sort_unstable();
            let mut chunked = Vec::new();
            for w in bounds.windows(2) {
                chunked.extend(run(&mut sf, &data[w[0] * nc..w[1] * nc], nc));
            }
            prop_assert_eq!(
                whole.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                chunked.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
        }
    }
}
