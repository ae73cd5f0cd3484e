//! The DRNL's lane-parallel filter cascade: the sections across `W` channels, a group's
//! coefficients and state, and the two SIMD kernels (CASP and MAP) that run a group over
//! a time block, compiled per instruction set by `simd_kernel!`. Apart from the
//! filterbank, which groups the channels and calls them block by block.

use super::compression::{casp_compress, map_compress};
use super::design::Biquad;

/// States per channel: CASP lin GT ×2, lin LP ×4, nl GT ×2 + ×2, nl LP ×1; MAP uses 9
/// (GT ×3 on each of the three stages).
pub(super) const STATES: usize = 11;

/// A `gt_section` across `W` channels. Its `b2 = 0`, so the DF2T's `z1 = b2·x − a2·y`
/// is `(−a2)·y`: the same value without the product by zero (only the sign of an exact
/// zero state can differ).
#[derive(Debug, Clone, Copy)]
pub(super) struct LaneGt<const W: usize> {
    b0: [f64; W],
    b1: [f64; W],
    /// `−a1`, `−a2`: `z + (−a)·y` is `z − a·y` bit for bit.
    na1: [f64; W],
    na2: [f64; W],
}

impl<const W: usize> LaneGt<W> {
    pub(super) const ZERO: Self = LaneGt {
        b0: [0.0; W],
        b1: [0.0; W],
        na1: [0.0; W],
        na2: [0.0; W],
    };

    pub(super) fn set(&mut self, lane: usize, s: &Biquad) {
        self.b0[lane] = s.b[0];
        self.b1[lane] = s.b[1];
        self.na1[lane] = -s.a[0];
        self.na2[lane] = -s.a[1];
    }

    /// One sample `x` of lane `l`: DF2T in the reference's order, `y = z0 + b0·x`,
    /// `z0 = (z1 − a1·y) + b1·x`, `z1 = −a2·y`; returns `y`.
    #[inline(always)]
    fn step(&self, z: &mut [[f64; W]; 2], l: usize, x: f64) -> f64 {
        let y = z[0][l] + self.b0[l] * x;
        z[0][l] = (z[1][l] + self.na1[l] * y) + self.b1[l] * x;
        z[1][l] = self.na2[l] * y;
        y
    }

    /// The section over `buf` (rows of `W` channels) in place, state `z` carried.
    #[inline(always)]
    fn run(&self, z: &mut [[f64; W]; 2], buf: &mut [[f64; W]]) {
        self.run_then(z, buf, |_| ());
    }

    /// [`LaneGt::run`], then `then` on each output row in place (in the same pass, so that
    /// its work overlaps the recursion's latency).
    #[inline(always)]
    fn run_then(
        &self,
        z: &mut [[f64; W]; 2],
        buf: &mut [[f64; W]],
        mut then: impl FnMut(&mut [f64; W]),
    ) {
        let mut zs = *z;
        for v in buf.iter_mut() {
            for (l, x) in v.iter_mut().enumerate() {
                *x = self.step(&mut zs, l, *x);
            }
            then(v);
        }
        *z = zs;
    }

    /// The section on `gain·x` (each lane's gain times the one input sample of a row),
    /// written to `buf`: the paths' input scaling in the first section's pass.
    #[inline(always)]
    fn run_from(&self, z: &mut [[f64; W]; 2], x: &[f64], gain: &[f64; W], buf: &mut [[f64; W]]) {
        let mut zs = *z;
        for (v, &xt) in buf.iter_mut().zip(x) {
            for l in 0..W {
                v[l] = self.step(&mut zs, l, gain[l] * xt);
            }
        }
        *z = zs;
    }
}

/// A section given by its one-sample `step` (e.g. [`LaneGt::step`]) over `buf`, writing
/// `other + y` to `W` values at every `stride` of `out` instead of `y` to `buf`: the
/// paths' sum in the last section's pass. State `z` carried.
#[inline(always)]
fn sum_into<const W: usize>(
    z: &mut [[f64; W]; 2],
    buf: &[[f64; W]],
    other: &[[f64; W]],
    out: &mut [f64],
    stride: usize,
    step: impl Fn(&mut [[f64; W]; 2], usize, f64) -> f64,
) {
    let mut zs = *z;
    for (t, (v, o)) in buf.iter().zip(other).enumerate() {
        let row = &mut out[t * stride..t * stride + W];
        for l in 0..W {
            row[l] = o[l] + step(&mut zs, l, v[l]);
        }
    }
    *z = zs;
}

/// An `lp_section` across `W` channels. Its numerator is `[C, 2C, C]`, and `(2C)·x` is
/// `C·x + C·x` bit for bit (scaling by 2 is exact), so one product serves all three.
#[derive(Debug, Clone, Copy)]
pub(super) struct LaneLp<const W: usize> {
    c: [f64; W],
    /// `−a1`, `−a2`.
    na1: [f64; W],
    na2: [f64; W],
}

impl<const W: usize> LaneLp<W> {
    pub(super) const ZERO: Self = LaneLp {
        c: [0.0; W],
        na1: [0.0; W],
        na2: [0.0; W],
    };

    pub(super) fn set(&mut self, lane: usize, s: &Biquad) {
        self.c[lane] = s.b[0];
        self.na1[lane] = -s.a[0];
        self.na2[lane] = -s.a[1];
    }

    /// One sample `x` of lane `l` (see [`LaneGt::step`]): `y = z0 + C·x`,
    /// `z0 = (z1 − a1·y) + 2C·x`, `z1 = C·x − a2·y`; returns `y`.
    #[inline(always)]
    fn step(&self, z: &mut [[f64; W]; 2], l: usize, x: f64) -> f64 {
        let cx = self.c[l] * x;
        let y = z[0][l] + cx;
        z[0][l] = (z[1][l] + self.na1[l] * y) + (cx + cx);
        z[1][l] = cx + self.na2[l] * y;
        y
    }

    /// The section over `buf` in place, state `z` carried.
    #[inline(always)]
    fn run(&self, z: &mut [[f64; W]; 2], buf: &mut [[f64; W]]) {
        let mut zs = *z;
        for v in buf.iter_mut() {
            for (l, x) in v.iter_mut().enumerate() {
                *x = self.step(&mut zs, l, *x);
            }
        }
        *z = zs;
    }
}

/// Coefficients and state of `W` channels, lane-major (unused lanes of a narrow bank
/// have zero coefficients and compute zeros that are never written out).
#[derive(Debug, Clone)]
pub(super) struct Group<const W: usize> {
    pub(super) lin_gain: [f64; W],
    /// Non-linear path input gain `mocIpsi·mocContra`.
    pub(super) moc: [f64; W],
    pub(super) gt_lin: LaneGt<W>,
    pub(super) lp_lin: LaneLp<W>,
    pub(super) gt_nl: LaneGt<W>,
    pub(super) lp_nl: LaneLp<W>,
    /// The per-channel compression constants (see [`ChannelDesign::compression`]).
    ///
    /// [`ChannelDesign::compression`]: super::design::ChannelDesign::compression
    pub(super) comp: [[f64; W]; 2],
    pub(super) z: [[[f64; W]; 2]; STATES],
}

/// The two paths of a group over one time block, `[time][lane]`.
#[derive(Debug, Clone)]
pub(super) struct Paths<const W: usize> {
    pub(super) lin: Vec<[f64; W]>,
    pub(super) nl: Vec<[f64; W]>,
}

afe_core::simd_kernel!(
    fma,
    /// CASP: `lin = LP⁴(GT²(g·x))`, `nlin = LP(GT²(compress(GT²(moc·x))))`, out `lin + nlin`,
    /// for one group over one time block (at most the paths' length), `stride` values per
    /// output row. Section by section over the block, so that each recursion keeps its
    /// state in registers and the lanes' independent recursions hide each other's latency.
    /// Compiled for AVX-512 and AVX2 + FMA too, chosen at run time; every lane does the
    /// scalar operations in order, so the numbers depend neither on the instruction set nor
    /// on the lane. The filters fuse no multiply-add (they keep the reference's roundings);
    /// only `ln_rough` does, whose result is scaled by `delta` (about 5e−9) far below
    /// the output's last bit.
    pub(super) fn run_casp<const W: usize>(
        g: &mut Group<W>,
        delta: f64,
        x: &[f64],
        paths: &mut Paths<W>,
        out: &mut [f64],
        stride: usize,
    ) {
        let lin = &mut paths.lin[..x.len()];
        let nl = &mut paths.nl[..x.len()];
        let z = &mut g.z;
        g.gt_lin.run_from(&mut z[0], x, &g.lin_gain, lin);
        g.gt_lin.run(&mut z[1], lin);
        for zs in &mut z[2..6] {
            g.lp_lin.run(zs, lin);
        }
        g.gt_nl.run_from(&mut z[6], x, &g.moc, nl);
        let [ca, cb] = g.comp;
        g.gt_nl.run_then(&mut z[7], nl, |v| {
            for l in 0..W {
                v[l] = casp_compress(v[l], ca[l], cb[l], delta);
            }
        });
        for zs in &mut z[8..10] {
            g.gt_nl.run(zs, nl);
        }
        let lp = &g.lp_nl;
        sum_into(&mut z[10], nl, lin, out, stride, |zs, l, x| {
            lp.step(zs, l, x)
        });
    }
);

afe_core::simd_kernel!(
    /// MAP: `lin = GT³(500·x)`, `nlin = GT³(compress(GT³(moc·x)))`, out `lin + nlin`, for
    /// one group over one time block of the middle-ear output (see [`run_casp`]).
    pub(super) fn run_map<const W: usize>(
        g: &mut Group<W>,
        ct_bm: f64,
        x: &[f64],
        paths: &mut Paths<W>,
        out: &mut [f64],
        stride: usize,
    ) {
        let lin = &mut paths.lin[..x.len()];
        let nl = &mut paths.nl[..x.len()];
        let z = &mut g.z;
        g.gt_lin.run_from(&mut z[0], x, &g.lin_gain, lin);
        for zs in &mut z[1..3] {
            g.gt_lin.run(zs, lin);
        }
        g.gt_nl.run_from(&mut z[3], x, &g.moc, nl);
        g.gt_nl.run(&mut z[4], nl);
        let [ca, cts] = g.comp;
        g.gt_nl.run_then(&mut z[5], nl, |v| {
            for l in 0..W {
                v[l] = map_compress(v[l], ca[l], cts[l], ct_bm);
            }
        });
        for zs in &mut z[6..8] {
            g.gt_nl.run(zs, nl);
        }
        let gt = &g.gt_nl;
        sum_into(&mut z[8], nl, lin, out, stride, |zs, l, x| {
            gt.step(zs, l, x)
        });
    }
);
