//! Windowed mean power per channel of a time-major frame, the kernel of the ratemap and
//! of the ILD (spec 16-ratemap, 17-ild): eight adjacent channels per vector, each
//! channel's terms added in time order whatever the width, so that every path gives the
//! same bits.

use crate::framing::Frame;
use crate::lanes::vector_start;

/// Windowed mean power of each channel of a time-major frame, `mean((w·x)²)`.
pub fn frame_power(win: &[f64], frame: Frame<'_>, out: &mut [f64]) {
    let nc = out.len();
    if nc < LANES {
        out.fill(0.0);
        for (w, z) in win.iter().zip(frame.rows()) {
            for (acc, v) in out.iter_mut().zip(z) {
                let x = w * v;
                *acc += x * x;
            }
        }
    } else {
        // Vectors of eight adjacent channels, the last one overlapping its neighbour
        // when `nc` is not a multiple of eight: every vector has its own accumulators,
        // and an overlapped channel gets the same sum from both.
        let start = |v: usize| vector_start(v, LANES, nc);
        let vectors = nc.div_ceil(LANES);
        for v in (0..vectors).step_by(4) {
            match vectors - v {
                1 => power_lanes(win, frame, [start(v)], out),
                2 => power_lanes(win, frame, [start(v), start(v + 1)], out),
                3 => power_lanes(win, frame, [v, v + 1, v + 2].map(start), out),
                _ => power_lanes(win, frame, [v, v + 1, v + 2, v + 3].map(start), out),
            }
        }
    }
    let n = win.len() as f64;
    for v in out.iter_mut() {
        *v /= n;
    }
}

/// Channels per vector of [`frame_power`].
const LANES: usize = 8;

crate::simd_kernel!(
    /// `Σ (win·x)²` over the frame for the `V` vectors of channels starting at `starts`,
    /// written (not yet divided by the length) into `out`; each channel's terms are added
    /// in time order, as on the scalar path.
    fn power_lanes<'a, const V: usize>(
        win: &[f64],
        frame: Frame<'a>,
        starts: [usize; V],
        out: &mut [f64],
    ) {
        let nc = out.len();
        let mut acc = [[0.0; LANES]; V];
        let mut n0 = 0;
        for part in [frame.head, frame.tail] {
            for (row, &w) in part.chunks_exact(nc).zip(&win[n0..]) {
                for (a, &c) in acc.iter_mut().zip(&starts) {
                    let z: [f64; LANES] = row[c..c + LANES].try_into().unwrap_or_default();
                    for l in 0..LANES {
                        let x = w * z[l];
                        a[l] += x * x;
                    }
                }
            }
            n0 += part.len() / nc;
        }
        for (a, &c) in acc.iter().zip(&starts) {
            out[c..c + LANES].copy_from_slice(a);
        }
    }
);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::window::window;

    #[test]
    fn frame_power_lanes_match_the_scalar_sum() {
        use crate::framing::FrameBuffer;
        for nc in [3, 8, 17, 24, 31, 40, 45, 61] {
            let x: Vec<f64> = (0..40 * nc)
                .map(|i| ((i * 7919) % 1009) as f64 / 1009.0 - 0.3)
                .collect();
            let win = window(crate::window::Window::Hann, 30);
            // Ten rows kept from a first chunk, twenty from the second: head and tail.
            let mut fb = FrameBuffer::new(nc, 30, 10);
            fb.advance(&x[..20 * nc], 1);
            let frame = fb.frame(&x[20 * nc..], 0);
            assert_eq!(frame.head.len(), 10 * nc);
            let mut out = vec![0.0; nc];
            frame_power(&win, frame, &mut out);
            for (c, got) in out.iter().enumerate() {
                let mut want = 0.0;
                for (n, w) in win.iter().enumerate() {
                    let v = w * x[(10 + n) * nc + c];
                    want += v * v;
                }
                want /= 30.0;
                assert_eq!(got.to_bits(), want.to_bits(), "{nc} channels, channel {c}");
            }
        }
    }
}
