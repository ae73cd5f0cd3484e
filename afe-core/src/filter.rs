//! Direct-form II transposed IIR filtering over time-major multichannel blocks.
//!
//! The recursion and its evaluation order are those of the reference (spec 01-P1):
//! `y = z0 + b0·x`, `z[i] = (z[i+1] − a[i+1]·y) + b[i+1]·x`, `z[m−1] = b[m]·x − a[m]·y`.
//! The order matters bit for bit on pole-clustered designs, so keep it.

use num_complex::Complex64;

/// Whether the denominator `1 + a[0]·z⁻¹ + … + a[n−1]·z⁻ⁿ` has all its roots inside
/// radius `rho`: the Schur–Cohn (step-down) test on the coefficients of the polynomial
/// with its roots divided by `rho` (`a[k]/ρ^{k+1}`), whose reflection coefficients are
/// then all of modulus below 1. With `rho` below 1, a filter that passes keeps a margin
/// of stability; the designs use it to tell whether an expanded (pole-clustered)
/// denominator, as computed, still has the poles it was designed with.
pub fn roots_within(a: &[Complex64], rho: f64) -> bool {
    let mut c: Vec<Complex64> = a.iter().zip(1..).map(|(v, k)| v / rho.powi(k)).collect();
    while let Some(&k) = c.last() {
        let kk = k.norm_sqr();
        if kk >= 1.0 || kk.is_nan() {
            return false;
        }
        let m = c.len();
        c = (0..m - 1)
            .map(|i| (c[i] - k * c[m - 2 - i].conj()) / (1.0 - kk))
            .collect();
    }
    true
}

/// Channels per SIMD vector of the multichannel path.
const LANES: usize = 8;
/// Vectors per pass of the multichannel path: their independent recursions hide each
/// other's latency. Four with AVX-512's 32 registers; two with AVX2's sixteen, where the
/// state of four second-order filters spills to memory (measured 1.1 to 1.5 times slower
/// per row at orders 2 and 4; no different at order 1).
fn max_vectors() -> usize {
    if crate::cpu::has_avx512() {
        4
    } else {
        2
    }
}
/// Highest order run with the state in registers; higher orders take the scalar path.
const MAX_LANE_ORDER: usize = 4;

/// A real DF2T filter applied independently to every channel of a time-major block.
///
/// Eight or more channels with an order up to 4 run across SIMD lanes, in place, with
/// the state in registers: passes of up to four vectors (two without AVX-512), each
/// vector loading eight adjacent channels of a row. When the channel count is not a
/// multiple of eight, the last vector of a pass overlaps its neighbour; the overlapping
/// channels then have two lanes with equal state that compute and store equal values.
/// Every channel sees exactly the scalar operations, so the numbers do not depend on the
/// path.
#[derive(Debug, Clone, PartialEq)]
pub struct Df2t {
    b: Vec<f64>,
    a: Vec<f64>,
    channels: usize,
    /// Passes of the multichannel path (empty on the scalar path).
    passes: Vec<Pass>,
    /// Channel of each state lane: the identity on the scalar path.
    lane_channel: Vec<usize>,
    /// State, `[order][lane]` so that the inner loop runs across channels.
    z: Vec<f64>,
}

/// Up to [`max_vectors`] vectors filtered together: their first channels and state lanes.
#[derive(Debug, Clone, PartialEq)]
struct Pass {
    starts: Vec<usize>,
    first_lane: usize,
}

/// Splits `channels` (≥ `LANES`) into passes of up to `vectors` whole vectors (see
/// [`Df2t`]).
fn plan_passes(channels: usize, vectors: usize) -> (Vec<Pass>, Vec<usize>) {
    let (mut passes, mut lane_channel) = (Vec::new(), Vec::new());
    let mut start = 0;
    while start < channels {
        let rest = channels - start;
        let full = LANES * vectors;
        // A pass leaves at least one whole vector for the next one.
        let size = if rest <= full {
            rest
        } else if rest - full < LANES {
            full - LANES
        } else {
            full
        };
        let end = start + size;
        let starts: Vec<usize> = (0..size.div_ceil(LANES))
            .map(|v| start + crate::lanes::vector_start(v, LANES, size))
            .collect();
        passes.push(Pass {
            first_lane: lane_channel.len(),
            starts: starts.clone(),
        });
        lane_channel.extend(starts.iter().flat_map(|s| *s..*s + LANES));
        start = end;
    }
    (passes, lane_channel)
}

impl Df2t {
    /// A filter with numerator `b` and denominator `a` (normalised by `a[0]`), for
    /// `channels` independent channels, with zero initial state.
    ///
    /// # Panics
    /// If `b` or `a` is empty or `a[0]` is zero.
    pub fn new(b: &[f64], a: &[f64], channels: usize) -> Self {
        assert!(
            !b.is_empty() && !a.is_empty() && a[0] != 0.0,
            "invalid filter"
        );
        let m = b.len().max(a.len());
        let mut bn = vec![0.0; m];
        let mut an = vec![0.0; m];
        for (d, s) in bn.iter_mut().zip(b) {
            *d = s / a[0];
        }
        for (d, s) in an.iter_mut().zip(a) {
            *d = s / a[0];
        }
        let (passes, lane_channel) = if channels >= LANES && (1..=MAX_LANE_ORDER).contains(&(m - 1))
        {
            plan_passes(channels, max_vectors())
        } else {
            (Vec::new(), (0..channels).collect())
        };
        Df2t {
            b: bn,
            a: an,
            channels,
            z: vec![0.0; (m - 1) * lane_channel.len()],
            passes,
            lane_channel,
        }
    }

    /// Filter order (number of states per channel).
    pub fn order(&self) -> usize {
        self.b.len() - 1
    }

    /// Filters `input` (time-major, `channels` values per row) into `output` (as long),
    /// carrying state: [`Df2t::process`] without a copy of the input first.
    pub fn process_from(&mut self, input: &[f64], output: &mut [f64]) {
        if self.passes.is_empty() {
            output.copy_from_slice(input);
            self.process(output);
        } else {
            self.process_lanes(Source::Input(input), output, self.channels);
        }
    }

    /// Filters `input` (time-major, `channels` values per row) into the first `channels`
    /// values of each `out_stride`-wide row of `output`, carrying state: one signal of
    /// several interleaved in a row (the AMS features' bands) without a copy.
    ///
    /// # Panics
    /// If `out_stride < channels` or `output` is too short for the rows of `input`.
    pub fn process_into_rows(&mut self, input: &[f64], output: &mut [f64], out_stride: usize) {
        let nc = self.channels;
        let rows = input.len() / nc.max(1);
        assert!(
            out_stride >= nc && (rows == 0 || output.len() >= (rows - 1) * out_stride + nc),
            "rows of {out_stride} for {rows} rows of {nc} channels"
        );
        if !self.passes.is_empty() {
            self.process_lanes(Source::Input(input), output, out_stride);
            return;
        }
        for (t, x) in input.chunks_exact(nc).enumerate() {
            let row = &mut output[t * out_stride..t * out_stride + nc];
            row.copy_from_slice(x);
            self.process(row);
        }
    }

    /// Filters the half-wave rectified `input`, `max(x, 0)`, into `output`: the
    /// rectifying inner-hair-cell models in one pass.
    pub fn process_rectified_from(&mut self, input: &[f64], output: &mut [f64]) {
        if self.passes.is_empty() {
            for (o, x) in output.iter_mut().zip(input) {
                *o = x.max(0.0);
            }
            self.process(output);
        } else {
            self.process_lanes(Source::Rectified(input), output, self.channels);
        }
    }

    /// Filters `data` (time-major, `channels` values per row) in place, carrying state.
    pub fn process(&mut self, data: &mut [f64]) {
        if !self.passes.is_empty() {
            self.process_lanes(Source::InPlace, data, self.channels);
            return;
        }
        let nc = self.channels;
        let m = self.order();
        let b = &self.b;
        let a = &self.a;
        for row in data.chunks_exact_mut(nc) {
            if m == 0 {
                for x in row.iter_mut() {
                    *x *= b[0];
                }
                continue;
            }
            for (c, x) in row.iter_mut().enumerate() {
                let xin = *x;
                let y = self.z[c] + b[0] * xin;
                for i in 0..m - 1 {
                    self.z[i * nc + c] = (self.z[(i + 1) * nc + c] - a[i + 1] * y) + b[i + 1] * xin;
                }
                self.z[(m - 1) * nc + c] = b[m] * xin - a[m] * y;
                *x = y;
            }
        }
    }

    /// The multichannel path, pass by pass over the whole block, writing rows of
    /// `out_stride` values.
    fn process_lanes(&mut self, input: Source<'_>, data: &mut [f64], out_stride: usize) {
        let lanes = self.lane_channel.len();
        let run = match self.order() {
            1 => run_lanes::<1>,
            2 => run_lanes::<2>,
            3 => run_lanes::<3>,
            _ => run_lanes::<4>,
        };
        for pass in &self.passes {
            let filter = (&self.b[..], &self.a[..]);
            let state = (&mut self.z[..], lanes, pass.first_lane);
            let strides = (self.channels, out_stride);
            run(filter, state, (input, data), strides, &pass.starts);
        }
    }

    /// Zeroes the state.
    pub fn reset(&mut self) {
        self.z.fill(0.0);
    }

    /// Sets every channel's first state to `value` (the other states are zeroed); used to
    /// seed one-pole smoothers.
    pub fn set_first_state(&mut self, channel: usize, value: f64) {
        assert!(
            channel < self.channels,
            "channel {channel} of {}",
            self.channels
        );
        let lanes = self.lane_channel.len();
        for (lane, _) in self
            .lane_channel
            .iter()
            .enumerate()
            .filter(|(_, c)| **c == channel)
        {
            for i in 0..self.order() {
                self.z[i * lanes + lane] = 0.0;
            }
            if self.order() > 0 {
                self.z[lane] = value;
            }
        }
    }
}

/// Where the multichannel path reads its input rows.
#[derive(Debug, Clone, Copy)]
enum Source<'a> {
    /// The output itself: filtering in place.
    InPlace,
    /// Another signal of the same shape.
    Input(&'a [f64]),
    /// Another signal, half-wave rectified on the way in.
    Rectified(&'a [f64]),
}

/// Filters the vectors of one pass (first channels `starts`) over every row of `data`
/// (`strides`: values per input row, and per row of `data`; read from `Source`), the
/// state of lanes `first..` of `z` (`[order][lanes]`) held in registers and the vectors
/// interleaved per row. Per lane, the operations are the scalar path's.
fn run_lanes<const M: usize>(
    filter: (&[f64], &[f64]),
    state: (&mut [f64], usize, usize),
    data: (Source<'_>, &mut [f64]),
    strides: (usize, usize),
    starts: &[usize],
) {
    match *starts {
        [s0] => lanes_kernel::<M, 1>(filter, state, data, strides, [s0]),
        [s0, s1] => lanes_kernel::<M, 2>(filter, state, data, strides, [s0, s1]),
        [s0, s1, s2] => lanes_kernel::<M, 3>(filter, state, data, strides, [s0, s1, s2]),
        [s0, s1, s2, s3, ..] => {
            lanes_kernel::<M, 4>(filter, state, data, strides, [s0, s1, s2, s3]);
        }
        [] => {}
    }
}

crate::simd_kernel!(
    fn lanes_kernel<const M: usize, const V: usize>(
        filter: (&[f64], &[f64]),
        state: (&mut [f64], usize, usize),
        (input, data): (Source<'_>, &mut [f64]),
        strides: (usize, usize),
        starts: [usize; V],
    ) {
        // One row loop per source, so that the loop itself carries no branch on it.
        match input {
            Source::InPlace => {
                lanes_loop::<M, V, false>(filter, state, None, data, strides, starts)
            }
            Source::Input(i) => {
                lanes_loop::<M, V, false>(filter, state, Some(i), data, strides, starts);
            }
            Source::Rectified(i) => {
                lanes_loop::<M, V, true>(filter, state, Some(i), data, strides, starts);
            }
        }
    }
);

/// The row loop of [`lanes_kernel`]: rows from `input` (half-wave rectified if
/// `RECTIFY`), or from `data` itself when `input` is `None`.
#[inline(always)]
fn lanes_loop<const M: usize, const V: usize, const RECTIFY: bool>(
    (b, a): (&[f64], &[f64]),
    (z, lanes, first): (&mut [f64], usize, usize),
    input: Option<&[f64]>,
    data: &mut [f64],
    (stride, out_stride): (usize, usize),
    starts: [usize; V],
) {
    let mut s = [[[0.0; LANES]; V]; M];
    for (i, si) in s.iter_mut().enumerate() {
        for (v, sv) in si.iter_mut().enumerate() {
            let at = i * lanes + first + v * LANES;
            sv.copy_from_slice(&z[at..at + LANES]);
        }
    }
    let (b0, bm, am) = (b[0], b[M], a[M]);
    let rows = input.map_or(data.len(), <[f64]>::len) / stride;
    for t in 0..rows {
        let row = &mut data[t * out_stride..t * out_stride + stride];
        let from = input.map_or(&*row, |i| &i[t * stride..(t + 1) * stride]);
        let mut x = [[0.0; LANES]; V];
        for (xv, &c) in x.iter_mut().zip(&starts) {
            xv.copy_from_slice(&from[c..c + LANES]);
            if RECTIFY {
                *xv = xv.map(|v| v.max(0.0));
            }
        }
        for v in 0..V {
            let mut y = [0.0; LANES];
            for l in 0..LANES {
                y[l] = s[0][v][l] + b0 * x[v][l];
            }
            for i in 0..M - 1 {
                for l in 0..LANES {
                    s[i][v][l] = (s[i + 1][v][l] - a[i + 1] * y[l]) + b[i + 1] * x[v][l];
                }
            }
            for l in 0..LANES {
                s[M - 1][v][l] = bm * x[v][l] - am * y[l];
            }
            row[starts[v]..starts[v] + LANES].copy_from_slice(&y);
        }
    }
    for (i, si) in s.iter().enumerate() {
        for (v, sv) in si.iter().enumerate() {
            let at = i * lanes + first + v * LANES;
            z[at..at + LANES].copy_from_slice(sv);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Schur–Cohn test on polynomials with known roots: 0.5 and 0.9 (real), and
    /// 0.8i with 0.3 (complex coefficients).
    #[test]
    fn roots_within_finds_the_largest_root() {
        let c = |re, im| Complex64::new(re, im);
        // (1 − 0.5z⁻¹)(1 − 0.9z⁻¹) = 1 − 1.4z⁻¹ + 0.45z⁻²
        let real = [c(-1.4, 0.0), c(0.45, 0.0)];
        assert!(roots_within(&real, 0.95) && roots_within(&real, 0.91));
        assert!(!roots_within(&real, 0.89) && !roots_within(&real, 0.5));
        // (1 − 0.8i·z⁻¹)(1 − 0.3z⁻¹) = 1 − (0.3 + 0.8i)z⁻¹ + 0.24i·z⁻²
        let complex = [c(-0.3, -0.8), c(0.0, 0.24)];
        assert!(roots_within(&complex, 0.81));
        assert!(!roots_within(&complex, 0.79));
        assert!(roots_within(&[], 0.1));
    }

    /// Direct evaluation of the difference equation, as an independent check.
    fn difference_equation(b: &[f64], a: &[f64], x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        for n in 0..x.len() {
            let mut acc = 0.0;
            for (k, bk) in b.iter().enumerate() {
                if n >= k {
                    acc += bk * x[n - k];
                }
            }
            for (k, ak) in a.iter().enumerate().skip(1) {
                if n >= k {
                    acc -= ak * y[n - k];
                }
            }
            y[n] = acc / a[0];
        }
        y
    }

    #[test]
    fn matches_difference_equation_and_is_chunk_invariant() {
        let b = [0.2, 0.3, -0.1];
        let a = [1.0, -0.5, 0.25];
        let x: Vec<f64> = (0..50).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let want = difference_equation(&b, &a, &x);
        // two channels: the second carries the same signal scaled by 2
        let mut data: Vec<f64> = x.iter().flat_map(|v| [*v, 2.0 * v]).collect();
        let mut f = Df2t::new(&b, &a, 2);
        let (first, second) = data.split_at_mut(2 * 17);
        f.process(first);
        f.process(second);
        for (n, w) in want.iter().enumerate() {
            assert!((data[2 * n] - w).abs() < 1e-12);
            assert!((data[2 * n + 1] - 2.0 * w).abs() < 1e-12);
        }
    }

    #[test]
    fn multichannel_lanes_match_single_channels_bit_for_bit() {
        // Orders 1–4 take the lane path (and 5 the scalar one); 3 channels the scalar
        // path, 8 one vector, 31 an overlapping vector, 35, 45 and 64 several passes.
        let coeffs: [(&[f64], &[f64]); 5] = [
            (&[0.3, 0.1], &[1.0, -0.6]),
            (&[0.2, 0.3, -0.1], &[1.0, -0.5, 0.25]),
            (&[0.1, 0.2, 0.2, 0.1], &[1.0, -0.9, 0.4, -0.05]),
            (&[0.05, 0.1, 0.1, 0.1, 0.05], &[1.0, -1.2, 0.8, -0.3, 0.05]),
            (
                &[0.05, 0.1, 0.1, 0.1, 0.1, 0.05],
                &[1.0, -1.2, 0.8, -0.3, 0.05, -0.01],
            ),
        ];
        for (b, a) in coeffs {
            for nc in [3, 8, 31, 35, 45, 64] {
                let rows = 300;
                let x: Vec<f64> = (0..rows * nc)
                    .map(|i| ((i * 7919 % 997) as f64 / 498.5 - 1.0) * (1 + i % 5) as f64)
                    .collect();
                let mut multi = Df2t::new(b, a, nc);
                multi.set_first_state(nc - 1, 0.25);
                let mut y = x.clone();
                let mut start = 0;
                for len in [1, 70, 129] {
                    multi.process(&mut y[start * nc..(start + len) * nc]);
                    start += len;
                }
                multi.process(&mut y[start * nc..]);
                for c in 0..nc {
                    let mut single = Df2t::new(b, a, 1);
                    if c == nc - 1 {
                        single.set_first_state(0, 0.25);
                    }
                    let mut col: Vec<f64> = (0..rows).map(|t| x[t * nc + c]).collect();
                    single.process(&mut col);
                    for (t, v) in col.iter().enumerate() {
                        assert_eq!(
                            v.to_bits(),
                            y[t * nc + c].to_bits(),
                            "order {}, {nc} channels, c={c}, t={t}",
                            a.len() - 1
                        );
                    }
                }
            }
        }
    }

    /// A sawtooth-like test signal of `rows` rows of `nc` channels, and two fresh filters
    /// of one second-order design over `nc` channels.
    fn signal_and_filters(rows: usize, nc: usize) -> (Vec<f64>, Df2t, Df2t) {
        let x = (0..rows * nc)
            .map(|i| ((i * 31) % 17) as f64 - 8.0)
            .collect();
        let (b, a) = ([0.2, 0.3, -0.1], [1.0, -0.5, 0.25]);
        (x, Df2t::new(&b, &a, nc), Df2t::new(&b, &a, nc))
    }

    #[test]
    fn filtering_from_an_input_equals_filtering_a_copy() {
        for nc in [1, 3, 31] {
            let (x, mut f, mut g) = signal_and_filters(100, nc);
            let mut copy = x.clone();
            f.process(&mut copy);
            let mut out = vec![0.0; x.len()];
            g.process_from(&x, &mut out);
            assert_eq!(copy, out, "{nc} channels");
            let (_, mut f, mut g) = signal_and_filters(100, nc);
            let mut rectified: Vec<f64> = x.iter().map(|v| v.max(0.0)).collect();
            f.process(&mut rectified);
            g.process_rectified_from(&x, &mut out);
            assert_eq!(rectified, out, "{nc} channels, rectified");
        }
    }

    /// Writing into wider rows gives the same values in the first columns of each row
    /// (across calls, both paths), and leaves the rest of every row alone.
    #[test]
    fn filtering_into_wider_rows_fills_only_the_first_columns() {
        for nc in [3, 31] {
            let rows = 90;
            let stride = 3 * nc + 2;
            let (x, mut f, mut g) = signal_and_filters(rows, nc);
            let mut copy = x.clone();
            f.process(&mut copy);
            let offset = nc + 1;
            let mut wide = vec![f64::NAN; offset + rows * stride];
            let split = 37;
            g.process_into_rows(&x[..split * nc], &mut wide[offset..], stride);
            let rest = &mut wide[offset + split * stride..offset + (rows - 1) * stride + nc];
            g.process_into_rows(&x[split * nc..], rest, stride);
            for (t, row) in copy.chunks_exact(nc).enumerate() {
                let at = offset + t * stride;
                assert_eq!(&wide[at..at + nc], row, "{nc} channels, row {t}");
            }
            let written = wide.iter().filter(|v| !v.is_nan()).count();
            assert_eq!(written, rows * nc, "{nc} channels: only the first columns");
        }
    }

    /// The passes, worked by hand for two and four vectors: whole passes while more than
    /// a vector remains after them; a last pass of under a vector's worth takes a vector
    /// from the pass before, and a pass not a multiple of eight ends on a vector
    /// overlapping its neighbour.
    #[test]
    fn passes_take_whole_vectors_and_leave_the_last_a_whole_one() {
        let starts = |channels, vectors| -> Vec<Vec<usize>> {
            let (passes, lanes) = plan_passes(channels, vectors);
            assert_eq!(
                lanes.len(),
                passes.iter().map(|p| 8 * p.starts.len()).sum::<usize>()
            );
            passes.into_iter().map(|p| p.starts).collect()
        };
        assert_eq!(starts(8, 4), [vec![0]]);
        assert_eq!(starts(31, 4), [vec![0, 8, 16, 23]]);
        assert_eq!(starts(32, 4), [vec![0, 8, 16, 24]]);
        // 8 left after a full pass: a pass of its own
        assert_eq!(starts(40, 4), [vec![0, 8, 16, 24], vec![32]]);
        // 4 left: the first pass gives up a vector
        assert_eq!(starts(36, 4), [vec![0, 8, 16], vec![24, 28]]);
        assert_eq!(starts(64, 4), [vec![0, 8, 16, 24], vec![32, 40, 48, 56]]);
        let (passes, lanes) = plan_passes(36, 4);
        assert_eq!(passes[1].first_lane, 24);
        assert_eq!(
            &lanes[24..40],
            &[24, 25, 26, 27, 28, 29, 30, 31, 28, 29, 30, 31, 32, 33, 34, 35]
        );
        assert_eq!(starts(15, 2), [vec![0, 7]]);
        assert_eq!(starts(31, 2), [vec![0, 8], vec![16, 23]]);
        assert_eq!(starts(24, 2), [vec![0, 8], vec![16]]);
        assert_eq!(starts(20, 2), [vec![0], vec![8, 12]]);
        assert_eq!(starts(36, 2), [vec![0, 8], vec![16], vec![24, 28]]);
    }

    /// Seeding sets a channel's first state (in both lanes where vectors overlap) and
    /// zeroes its others; the other channels keep their state. An order-0 filter has no
    /// state to seed.
    #[test]
    fn set_first_state_seeds_one_channel() {
        let (b, a) = ([0.2, 0.3, 0.1], [1.0, -0.5, 0.25]);
        for nc in [3, 9] {
            let mut f = Df2t::new(&b, &a, nc);
            let mut warm: Vec<f64> = (0..4 * nc).map(|i| (i as f64 * 0.7).sin()).collect();
            f.process(&mut warm);
            let mut untouched = f.clone();
            // of 9 channels, channel 7 lies in both vectors (channels 0–7 and 1–8)
            let c = nc - 2;
            f.set_first_state(c, 2.0);
            let mut y = vec![0.0; 2 * nc];
            let mut y0 = vec![0.0; 2 * nc];
            f.process(&mut y);
            untouched.process(&mut y0);
            assert_eq!(y[c], 2.0, "{nc} channels");
            // y1 = z1 − a1·y0 with z1 zeroed
            assert_eq!(y[nc + c], 0.5 * 2.0, "{nc} channels");
            for ch in (0..nc).filter(|&ch| ch != c) {
                assert_eq!((y[ch], y[nc + ch]), (y0[ch], y0[nc + ch]), "{nc}: {ch}");
            }
        }
        let mut gain = Df2t::new(&[2.0], &[1.0], 9);
        gain.set_first_state(3, 1.0);
        let mut x = vec![1.0; 9];
        gain.process(&mut x);
        assert_eq!(x, [2.0; 9]);
    }

    /// An order-0 filter is a gain, on the scalar path too.
    #[test]
    fn an_order_zero_filter_scales_by_b0_over_a0() {
        let mut f = Df2t::new(&[3.0], &[2.0], 3);
        let mut x = vec![1.0, -2.0, 4.0, 0.5, 0.0, -1.0];
        f.process(&mut x);
        assert_eq!(x, [1.5, -3.0, 6.0, 0.75, 0.0, -1.5]);
    }

    #[test]
    fn reset_restores_zero_state() {
        let mut f = Df2t::new(&[1.0], &[1.0, -0.9], 1);
        let mut x = vec![1.0, 0.0, 0.0];
        f.process(&mut x);
        f.reset();
        let mut y = vec![1.0, 0.0, 0.0];
        f.process(&mut y);
        assert_eq!(y, vec![1.0, 0.9, 0.9 * 0.9]);
    }
}
