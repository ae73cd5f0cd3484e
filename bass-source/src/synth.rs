//! Synthetic binaural test signals: tones, seeded noise, silence, with a chosen ITD and
//! ILD between the ears.

use std::str::FromStr;

use crate::error::{Error, Result};
use crate::placed::{Ears, Placed};
use crate::port::PortFormat;
use crate::source::{Clock, Source};

/// Largest |`ild_db`| accepted: a gain of 10^10 (or its inverse) on the right ear; more
/// would not be a level difference but an overflow to infinity.
pub const MAX_ILD_DB: f64 = 200.0;

/// What to synthesise, parsed from `key=value` pairs separated by commas, e.g.
/// `fs=44100,tone=440,noise=0.1,itd_ms=0.4,ild_db=-6,seed=1`.
///
/// | key | meaning | default |
/// |---|---|---|
/// | `fs` | sampling rate, Hz (integer) | 44100 |
/// | `tone` | a sine tone at this frequency, Hz (repeat the key for several) | none |
/// | `amp` | peak amplitude of each tone (full scale = 1.0) | 0.5 |
/// | `noise` | RMS of white Gaussian noise added to the tones | 0 |
/// | `seed` | seed of the noise (integer) | 1 |
/// | `itd_ms` | interaural time difference, ms, with the sign of the AFE's `itd`: > 0 delays the left ear | 0 |
/// | `ild_db` | level of the right ear relative to the left, dB (the AFE's `ild`) | 0 |
/// | `silence` | (no value) zeros on both ears; no `tone` nor `noise` allowed | |
/// | `az` | the source's azimuth in the world, deg (0 ahead, 90 to the left), heard by a rigid sphere; excludes `itd_ms` and `ild_db` | none |
/// | `radius` | with `az`: the sphere's radius, m | 0.075 |
/// | `turn` | with `az`: the head turns to this yaw, deg (positive to the left), and back | 0 |
/// | `turn_s` | with `turn`: how long each turn out and back takes, s | 2 |
///
/// With neither tones nor noise the signal is silence. The ITD is applied as a delay of
/// `round(itd_ms · fs / 1000)` whole samples of the lagging ear (its first samples are
/// zeros); the ILD as a gain of `10^(ild_db/20)` on the right ear. With `az`, the ears
/// differ by Woodworth's interaural delay for the azimuth relative to the head at each
/// sample, a fractional delay and no level difference ([`Placed`]); with `turn` the head
/// sweeps out and back again and again, and a stream reports its yaw to the processors
/// (`afe stream`'s tracking sees the head turn).
#[derive(Debug, Clone, PartialEq)]
pub struct SynthSpec {
    /// Sampling rate in Hz.
    pub fs: u32,
    /// Frequencies of the tones, in Hz.
    pub tones_hz: Vec<f64>,
    /// Peak amplitude of each tone (full scale = 1.0).
    pub amp: f64,
    /// RMS of the white Gaussian noise (full scale = 1.0).
    pub noise_rms: f64,
    /// Seed of the noise.
    pub seed: u64,
    /// Interaural time difference in ms, the AFE's `itd` sign (> 0: the left ear lags).
    pub itd_ms: f64,
    /// Level of the right ear relative to the left, in dB.
    pub ild_db: f64,
    /// Where the source is in the world, heard by a sphere that may turn (`az=`).
    pub placed: Option<Placed>,
}

impl Default for SynthSpec {
    fn default() -> Self {
        SynthSpec {
            fs: 44_100,
            tones_hz: Vec::new(),
            amp: 0.5,
            noise_rms: 0.0,
            seed: 1,
            itd_ms: 0.0,
            ild_db: 0.0,
            placed: None,
        }
    }
}

impl FromStr for SynthSpec {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        let fail = |reason: String| Error::SynthSpec {
            spec: text.to_string(),
            reason,
        };
        let mut spec = SynthSpec::default();
        let mut silence = false;
        let mut placed = Placed::at(0.0);
        let mut placing = Vec::new();
        for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            if item == "silence" {
                silence = true;
                continue;
            }
            let (key, value) = item.split_once('=').ok_or_else(|| {
                fail(format!(
                    "'{item}' is not of the form key=value (or 'silence')"
                ))
            })?;
            let number = || -> Result<f64> {
                value
                    .trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| fail(format!("{key}={value}: expected a finite number")))
            };
            let positive = |v: f64| {
                if v > 0.0 {
                    Ok(v)
                } else {
                    Err(fail(format!("{key}={value}: expected a number > 0")))
                }
            };
            let non_negative = |v: f64| {
                if v >= 0.0 {
                    Ok(v)
                } else {
                    Err(fail(format!("{key}={value}: expected a number ≥ 0")))
                }
            };
            match key.trim() {
                "fs" => {
                    spec.fs = value
                        .trim()
                        .parse::<u32>()
                        .ok()
                        .filter(|v| *v > 0)
                        .ok_or_else(|| {
                            fail(format!("fs={value}: expected an integer rate in Hz > 0"))
                        })?;
                }
                "tone" => spec.tones_hz.push(positive(number()?)?),
                "amp" => spec.amp = non_negative(number()?)?,
                "noise" => spec.noise_rms = non_negative(number()?)?,
                "seed" => {
                    spec.seed = value
                        .trim()
                        .parse()
                        .map_err(|_| fail(format!("seed={value}: expected an integer ≥ 0")))?;
                }
                "itd_ms" => {
                    spec.itd_ms = number()?;
                    if spec.itd_ms.abs() > 1000.0 {
                        return Err(fail(format!(
                            "itd_ms={value}: interaural delays beyond ±1000 ms are not supported"
                        )));
                    }
                }
                "ild_db" => {
                    spec.ild_db = number()?;
                    if spec.ild_db.abs() > MAX_ILD_DB {
                        return Err(fail(format!(
                            "ild_db={value}: interaural level differences beyond ±{MAX_ILD_DB} dB \
                             are not supported"
                        )));
                    }
                }
                "az" => placed.azimuth_deg = number()?,
                "radius" => {
                    placed.radius_m = positive(number()?)?;
                    if placed.radius_m > 1.0 {
                        return Err(fail(format!(
                            "radius={value}: a head's radius in m, at most 1"
                        )));
                    }
                }
                "turn" => {
                    placed.turn_deg = number()?;
                    if placed.turn_deg.abs() > 180.0 {
                        return Err(fail(format!("turn={value}: a yaw in deg, within ±180")));
                    }
                }
                "turn_s" => placed.turn_s = positive(number()?)?,
                other => {
                    return Err(fail(format!(
                        "unknown key '{other}' (keys: fs, tone, amp, noise, seed, itd_ms, ild_db, \
                         silence, az, radius, turn, turn_s)"
                    )))
                }
            }
            if matches!(key.trim(), "az" | "radius" | "turn" | "turn_s") {
                placing.push(key.trim());
            }
        }
        if !placing.is_empty() {
            if !placing.contains(&"az") {
                return Err(fail(format!(
                    "{} place a source heard by a sphere: give its azimuth too (az=DEG)",
                    placing.join(", ")
                )));
            }
            if spec.itd_ms != 0.0 || spec.ild_db != 0.0 {
                return Err(fail(
                    "az places the source, which gives the ears' differences: itd_ms and ild_db \
                     are not given with it"
                        .into(),
                ));
            }
            spec.placed = Some(placed);
        }
        if silence && (!spec.tones_hz.is_empty() || spec.noise_rms > 0.0) {
            return Err(fail("'silence' excludes tone and noise".into()));
        }
        let nyquist = f64::from(spec.fs) / 2.0;
        if let Some(f) = spec.tones_hz.iter().find(|f| **f >= nyquist) {
            return Err(fail(format!(
                "tone={f} is not below the Nyquist frequency fs/2 = {nyquist} Hz"
            )));
        }
        Ok(spec)
    }
}

/// A source of the binaural signal a [`SynthSpec`] describes, as `f64` samples.
#[derive(Debug, Clone)]
pub struct Synth {
    spec: SynthSpec,
    format: PortFormat,
    /// Next frame index.
    t: u64,
    rng: u64,
    /// Last `delay.len()` samples of the leading ear: the lagging ear's input.
    delay: Vec<f64>,
    delay_pos: usize,
    right_lags: bool,
    right_gain: f64,
    /// With `az` (the spec's `placed`): the ears of the placed source.
    ears: Option<Ears>,
}

impl Synth {
    /// A synthesiser of `spec`, two channels (left, right), chunked with BASS's timing
    /// ([`PortFormat::bass_timing`]).
    pub fn new(spec: SynthSpec) -> Self {
        let format = PortFormat::bass_timing(spec.fs, 2);
        let delay = (spec.itd_ms * f64::from(spec.fs) / 1000.0).round().abs() as usize;
        Synth {
            format,
            t: 0,
            rng: spec.seed,
            delay: vec![0.0; delay],
            delay_pos: 0,
            right_lags: spec.itd_ms < 0.0,
            right_gain: 10f64.powf(spec.ild_db / 20.0),
            ears: spec
                .placed
                .map(|p| Ears::new(p.max_lag_s() * f64::from(spec.fs))),
            spec,
        }
    }

    /// Parses `spec` (see [`SynthSpec`]) and builds its synthesiser.
    pub fn parse(spec: &str) -> Result<Self> {
        spec.parse().map(Synth::new)
    }

    /// The specification.
    pub fn spec(&self) -> &SynthSpec {
        &self.spec
    }

    /// splitmix64: the next 64 random bits.
    fn next_u64(&mut self) -> u64 {
        self.rng = self.rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A standard normal deviate (Box–Muller).
    fn gaussian(&mut self) -> f64 {
        let unit = |bits: u64| ((bits >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
        let u1 = unit(self.next_u64());
        let u2 = unit(self.next_u64());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// The next sample of the signal before ITD and ILD.
    fn next_sample(&mut self) -> f64 {
        let fs = f64::from(self.spec.fs);
        let t = self.t as f64;
        let mut s = 0.0;
        for f in &self.spec.tones_hz {
            s += self.spec.amp * (std::f64::consts::TAU * (t * f / fs).fract()).sin();
        }
        if self.spec.noise_rms > 0.0 {
            s += self.spec.noise_rms * self.gaussian();
        }
        self.t += 1;
        s
    }
}

impl Source for Synth {
    type Sample = f64;

    fn format(&self) -> PortFormat {
        self.format
    }

    fn clock(&self) -> Clock {
        Clock::OnDemand
    }

    fn read_chunk(&mut self, out: &mut [Vec<f64>], max_frames: usize) -> Result<usize> {
        let [left, right] = out else {
            return Err(Error::ChannelCount {
                expected: 2,
                actual: out.len(),
            });
        };
        left.clear();
        right.clear();
        if let (Some(placed), Some(mut ears)) = (self.spec.placed, self.ears.take()) {
            let fs = f64::from(self.spec.fs);
            for _ in 0..max_frames {
                let lag = placed.right_lag_s(self.t as f64 / fs) * fs;
                let (l, r) = ears.hear(self.next_sample(), lag);
                left.push(l);
                right.push(r);
            }
            self.ears = Some(ears);
            return Ok(max_frames);
        }
        for _ in 0..max_frames {
            let lead = self.next_sample();
            let lag = match self.delay.get_mut(self.delay_pos) {
                Some(slot) => std::mem::replace(slot, lead),
                None => lead,
            };
            self.delay_pos = (self.delay_pos + 1) % self.delay.len().max(1);
            let (l, r) = if self.right_lags {
                (lead, lag)
            } else {
                (lag, lead)
            };
            left.push(l);
            right.push(r * self.right_gain);
        }
        Ok(max_frames)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn render(spec: &str, frames: usize) -> [Vec<f64>; 2] {
        let mut s = Synth::parse(spec).expect("spec");
        let mut out = [Vec::new(), Vec::new()];
        let mut all = [Vec::new(), Vec::new()];
        let mut left = frames;
        while left > 0 {
            let n = s.read_chunk(&mut out, left.min(300)).expect("read");
            for c in 0..2 {
                all[c].extend_from_slice(&out[c]);
            }
            left -= n;
        }
        all
    }

    fn rms(x: &[f64]) -> f64 {
        (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
    }

    #[test]
    fn the_issue_example_parses() {
        let spec: SynthSpec = "fs=44100,tone=440,noise=0.1,itd_ms=0.4,ild_db=-6,seed=1"
            .parse()
            .expect("spec");
        assert_eq!(
            spec,
            SynthSpec {
                fs: 44100,
                tones_hz: vec![440.0],
                amp: 0.5,
                noise_rms: 0.1,
                seed: 1,
                itd_ms: 0.4,
                ild_db: -6.0,
                placed: None,
            }
        );
    }

    #[test]
    fn itd_and_ild_are_what_was_asked() {
        // -0.5 ms at 16 kHz: the right ear lags by 8 samples; right 6 dB down
        let [l, r] = render(
            "fs=16000,tone=500,tone=1300,noise=0.05,itd_ms=-0.5,ild_db=-6",
            4000,
        );
        let g = 10f64.powf(-6.0 / 20.0);
        assert!(r[..8].iter().all(|v| *v == 0.0));
        for t in 8..4000 {
            assert!((r[t] - g * l[t - 8]).abs() < 1e-12, "frame {t}");
        }
        let [l2, r2] = render("fs=16000,tone=500,itd_ms=0.5", 100);
        assert_eq!(&l2[8..], &r2[..92], "positive ITD: the left ear lags");
        assert!(l2[..8].iter().all(|v| *v == 0.0));
    }

    #[test]
    fn noise_has_its_rms_and_its_seed() {
        let a = render("fs=8000,noise=0.1,seed=7", 20000);
        let b = render("fs=8000,noise=0.1,seed=7", 20000);
        let c = render("fs=8000,noise=0.1,seed=8", 20000);
        assert_eq!(a, b);
        assert_ne!(a[0], c[0]);
        assert!((rms(&a[0]) - 0.1).abs() < 0.003, "{}", rms(&a[0]));
        let mean = a[0].iter().sum::<f64>() / a[0].len() as f64;
        assert!(mean.abs() < 0.003, "{mean}");
    }

    #[test]
    fn tones_and_silence() {
        let [l, _] = render("fs=8000,tone=1000,amp=0.25", 800);
        assert!((rms(&l) - 0.25 / 2f64.sqrt()).abs() < 1e-9);
        assert!(
            (l[2] - 0.25).abs() < 1e-12,
            "sin(π/2) at 1/4 of a 1 kHz period"
        );
        let [l, r] = render("fs=8000,silence", 100);
        assert!(l.iter().chain(&r).all(|v| *v == 0.0));
    }

    #[test]
    fn bad_specs_say_what_is_wrong() {
        let err = |s: &str| s.parse::<SynthSpec>().expect_err(s).to_string();
        assert!(err("fs=44100,tone=abc").contains("tone=abc: expected a finite number"));
        assert!(err("fs=0").contains("expected an integer rate"));
        assert!(err("tone=30000").contains("Nyquist"));
        assert!(err("freq=440").contains("unknown key 'freq'"));
        assert!(err("tone").contains("not of the form key=value"));
        assert!(err("silence,tone=440").contains("excludes"));
        assert!(err("noise=-1").contains("≥ 0"));
        assert!(err("turn=30").contains("give its azimuth too (az=DEG)"));
        assert!(err("az=30,itd_ms=0.2").contains("not given with it"));
        assert!(err("az=30,turn=200").contains("within ±180"));
        assert!(err("az=30,radius=0").contains("> 0"));
        assert!(err("az=30,turn_s=-1").contains("> 0"));
    }

    /// How much later the right ear hears a tone of `f_hz` than the left over `range`
    /// (whole periods), s, from the tone's phase at each ear.
    fn right_lag_s(l: &[f64], r: &[f64], f_hz: f64, fs: f64, range: std::ops::Range<usize>) -> f64 {
        let w = std::f64::consts::TAU * f_hz / fs;
        let phase = |x: &[f64]| {
            let (re, im) = range.clone().fold((0.0, 0.0), |(re, im), t| {
                (
                    re + x[t] * (w * t as f64).cos(),
                    im - x[t] * (w * t as f64).sin(),
                )
            });
            f64::atan2(im, re)
        };
        let (pi, tau) = (std::f64::consts::PI, std::f64::consts::TAU);
        ((phase(l) - phase(r) + pi).rem_euclid(tau) - pi) / (tau * f_hz)
    }

    #[test]
    fn a_placed_source_reaches_the_far_ear_woodworths_delay_later() {
        // at 48 kHz a source on the left of a 7.5-cm sphere: 0.562 ms, 27 samples
        let spec: SynthSpec = "fs=48000,tone=500,az=90".parse().expect("spec");
        let placed = spec.placed.expect("placed");
        assert!((placed.max_lag_s() * 48000.0 - 26.98).abs() < 0.01);
        let [l, r] = render("fs=48000,tone=500,az=90", 9600);
        let lag = right_lag_s(&l, &r, 500.0, 48000.0, 96..9600);
        assert!((lag - placed.max_lag_s()).abs() < 1e-7, "{lag}");
        let [l, r] = render("fs=48000,tone=500,az=300,radius=0.0875", 9600);
        let expected = -0.0875 / 343.0 * (60f64.to_radians() + 0.75f64.sqrt());
        let lag = right_lag_s(&l, &r, 500.0, 48000.0, 96..9600);
        assert!((lag - expected).abs() < 1e-7, "{lag} for {expected}");
        let [l, r] = render("fs=48000,noise=0.1,az=0", 2000);
        assert_eq!(l, r, "straight ahead both ears hear the same");
    }

    #[test]
    fn a_turning_head_hears_the_source_move_the_other_way() {
        // the source at 60 deg; the head turns to 60 at 1 s: the source is then ahead
        let [l, r] = render("fs=16000,tone=250,az=60,turn=60,turn_s=2", 32000);
        let lag = |from: usize| right_lag_s(&l, &r, 250.0, 16000.0, from..from + 320);
        let start = Placed::at(60.0).right_lag_s(0.0);
        assert!(
            (lag(64) - start).abs() < 2e-6,
            "the source on the left first: {}",
            lag(64)
        );
        assert!(lag(15840).abs() < 2e-6, "ahead at 1 s: {}", lag(15840));
        assert!(
            (lag(31616) - start).abs() < 2e-6,
            "back by 2 s: {}",
            lag(31616)
        );
    }
}
