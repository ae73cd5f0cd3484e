//! The RAA's interaural time difference per frame and band, from the adaptation output
//! before its low-pass (van Dorp Schuitman's Fig. 3.10, as the AFE's `afeRAA` computes
//! it): 50-ms frames with a hop of 25 ms under a two-sided exponential window, the
//! cross-correlation's first maximum within ±700 µs, refined by a parabola.

use afe_core::Block;

/// Frame length, s (rounded to an even number of samples).
pub const FRAME_S: f64 = 0.05;
/// Frame hop, s.
pub const HOP_S: f64 = 0.025;
/// Time constant of the two-sided exponential window `exp(−0.5·|n| / (τ·fs))`, s.
const WINDOW_TAU_S: f64 = 0.03;
/// Largest lag searched, s.
const MAX_DELAY_S: f64 = 700e-6;

/// The frame geometry at a sampling rate, in samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Framing {
    /// Frame length: `2·round(FRAME_S·fs/2)`.
    pub size: usize,
    /// Hop: `round(HOP_S·fs)`.
    pub hop: usize,
    /// Largest lag: `ceil(700e-6·fs)`.
    pub max_lag: usize,
}

impl Framing {
    /// The geometry at `fs` Hz.
    pub fn at(fs: f64) -> Self {
        Framing {
            size: 2 * (FRAME_S * fs / 2.0).round() as usize,
            hop: (HOP_S * fs).round() as usize,
            max_lag: (MAX_DELAY_S * fs).ceil() as usize,
        }
    }

    /// Whole frames in `samples`: `floor((samples − (size − hop)) / hop)`, 0 when none fits.
    pub fn frames(&self, samples: usize) -> usize {
        (samples + self.hop)
            .checked_sub(self.size)
            .map_or(0, |n| n / self.hop)
    }

    /// 0-based sample at which frame `k`'s direct/reverberant weight is taken: its start
    /// plus half a frame, the sample the window weighs most.
    pub fn centre(&self, k: usize) -> usize {
        k * self.hop + self.size / 2
    }
}

/// ITD per frame and band (`[frame][band]`) of the adaptation outputs `left` and `right`
/// (`[sample][band]`), in the AFE's unit: lag in samples times the hop in seconds, i.e.
/// `fs · HOP_S` times the physical delay in s (400× at 16 kHz); positive when the right
/// ear leads.
pub fn itd(left: &Block, right: &Block, fs: f64) -> Block {
    let framing = Framing::at(fs);
    let bands = left.width();
    let frames = framing.frames(left.frames());
    let half = framing.size as f64 / 2.0;
    let window: Vec<f64> = (0..framing.size)
        .map(|i| (-0.5 * (i as f64 - half).abs() / (WINDOW_TAU_S * fs)).exp())
        .collect();
    let lags = 2 * framing.max_lag + 1;
    let mut out = Block::from_vec(vec![0.0; frames * bands], bands);
    let (mut wl, mut wr) = (vec![0.0; framing.size], vec![0.0; framing.size]);
    let mut c = vec![0.0; lags];
    // the AFE divides the lag by the frame rate (1/hop, Hz), the quirk of the ITD's unit
    let frame_rate = 1.0 / HOP_S;
    for k in 0..frames {
        let start = k * framing.hop;
        for band in 0..bands {
            for (i, w) in window.iter().enumerate() {
                wl[i] = w * left.row(start + i)[band];
                wr[i] = w * right.row(start + i)[band];
            }
            cross_correlate(&wl, &wr, framing.max_lag, &mut c);
            out.as_mut_slice()[k * bands + band] = peak_lag(&c, framing.max_lag) / frame_rate;
        }
    }
    out
}

/// The direct and reverberant parts of `itd` (`[frame][band]`): `ITDdir = ζ·ITD` with ζ
/// the share of the ears (0, ½ or 1) whose direct-stream mask (`[sample][band]`) is set
/// at the frame's [`Framing::centre`], and `ITDrev = ITD − ITDdir`.
pub fn split(itd: &Block, mask_l: &[bool], mask_r: &[bool], fs: f64) -> (Block, Block) {
    let framing = Framing::at(fs);
    let bands = itd.width();
    let mut direct = itd.clone();
    for (k, row) in direct.as_mut_slice().chunks_exact_mut(bands).enumerate() {
        let t = framing.centre(k);
        for (band, v) in row.iter_mut().enumerate() {
            let i = t * bands + band;
            *v *= (f64::from(u8::from(mask_l[i])) + f64::from(u8::from(mask_r[i]))) / 2.0;
        }
    }
    let reverberant = itd
        .as_slice()
        .iter()
        .zip(direct.as_slice())
        .map(|(a, d)| a - d)
        .collect();
    (direct, Block::from_vec(reverberant, bands))
}

/// `c[max_lag + l] = Σₙ wl[n + l]·wr[n]` for `l = −max_lag … max_lag`: the AFE's
/// `real(ifft(fft(wl)·conj(fft(wr))))` at those lags, whose FFT length (at least
/// `2·len − 1`) leaves no circular wrap, so the sum is the same correlation.
fn cross_correlate(wl: &[f64], wr: &[f64], max_lag: usize, c: &mut [f64]) {
    let n = wl.len();
    for (j, out) in c.iter_mut().enumerate() {
        let lag = j as isize - max_lag as isize;
        let (l0, r0) = if lag >= 0 {
            (lag as usize, 0)
        } else {
            (0, lag.unsigned_abs())
        };
        let len = n - l0.max(r0);
        *out = wl[l0..l0 + len]
            .iter()
            .zip(&wr[r0..r0 + len])
            .map(|(a, b)| a * b)
            .sum();
    }
}

/// The lag, in samples, of the first maximum of `c` (lags `−max_lag … max_lag`), moved to
/// the vertex of the parabola through it and its neighbours unless it is on the border.
fn peak_lag(c: &[f64], max_lag: usize) -> f64 {
    let mut i = 0;
    for (j, v) in c.iter().enumerate() {
        if *v > c[i] {
            i = j;
        }
    }
    let lag = i as f64 - max_lag as f64;
    if i == 0 || i + 1 == c.len() {
        return lag;
    }
    let (lo, peak, hi) = (c[i - 1], c[i], c[i + 1]);
    lag + 0.5 * (lo - hi) / (lo - 2.0 * peak + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_at_16k_is_the_afes() {
        let f = Framing::at(16000.0);
        assert_eq!((f.size, f.hop, f.max_lag), (800, 400, 12));
        assert_eq!(f.frames(48000), 119);
        assert_eq!(f.frames(799), 0);
        assert_eq!(f.frames(800), 1);
        assert_eq!(f.centre(2), 1200);
    }

    #[test]
    fn a_delayed_left_ear_gives_a_positive_itd_of_the_delay_in_hop_units() {
        let fs = 16000.0;
        let n = 2400;
        // broadband, so that the correlation's peak is sharp and the parabola near exact
        let band = |t: usize| {
            let t = t as f64;
            (0.3 * t).sin() + (0.71 * t).sin() + (1.3 * t).sin() + (2.1 * t).sin()
        };
        let right: Vec<f64> = (0..n).map(band).collect();
        let left: Vec<f64> = (0..n)
            .map(|t| if t >= 3 { band(t - 3) } else { 0.0 })
            .collect();
        let out = itd(&Block::from_vec(left, 1), &Block::from_vec(right, 1), fs);
        assert_eq!(out.frames(), Framing::at(fs).frames(n));
        for k in 1..out.frames() {
            let v = out.row(k)[0];
            assert!((v - 3.0 * HOP_S).abs() < 0.05 * HOP_S, "frame {k}: {v}");
        }
    }

    #[test]
    fn the_direct_share_is_taken_at_each_frames_centre() {
        let fs = 16000.0;
        let itd = Block::from_vec(vec![0.2, -0.1, 0.2, -0.1], 2);
        // frame 0's centre is sample 400, frame 1's 800; two bands
        let (mut mask_l, mut mask_r) = (vec![false; 2 * 1200], vec![false; 2 * 1200]);
        mask_l[400 * 2] = true; // frame 0, band 0: left only
        mask_l[800 * 2 + 1] = true; // frame 1, band 1: both
        mask_r[800 * 2 + 1] = true;
        mask_r[401 * 2 + 1] = true; // frame 0, band 1, one sample past the centre: not taken
        let (direct, reverberant) = split(&itd, &mask_l, &mask_r, fs);
        assert_eq!(direct.as_slice(), &[0.1, 0.0, 0.0, -0.1]);
        assert_eq!(reverberant.as_slice(), &[0.1, -0.1, 0.2, 0.0]);
    }

    #[test]
    fn a_peak_on_the_border_keeps_its_integer_lag() {
        assert_eq!(peak_lag(&[3.0, 2.0, 1.0], 1), -1.0);
        assert_eq!(peak_lag(&[1.0, 2.0, 2.0], 1), 0.5);
        assert_eq!(peak_lag(&[1.0, 3.0, 1.0], 1), 0.0);
        // the first of equal maxima
        assert_eq!(peak_lag(&[1.0, 2.0, 1.0, 2.0, 1.0], 2), -1.0);
    }
}
