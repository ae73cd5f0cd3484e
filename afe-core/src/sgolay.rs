//! Savitzky–Golay smoothing, as MATLAB's `sgolayfilt(x, order, frame)` (spec 01-P13).
//!
//! Each output sample is the value at its position of the least-squares polynomial of
//! degree `order` through the `frame` input samples around it. Interior samples use the
//! centred fit; the first and last `(frame − 1)/2` samples use the fit over the first or
//! last `frame` samples, evaluated at their own positions (no padding).

use crate::error::{Error, Result};

/// A Savitzky–Golay smoother of one polynomial order and odd frame length.
#[derive(Debug, Clone, PartialEq)]
pub struct SavitzkyGolay {
    frame: usize,
    /// The projection `G = V (VᵀV)⁻¹ Vᵀ`, `frame × frame`, row-major: row `i` gives the
    /// fitted value at frame position `i` from the frame's samples.
    g: Vec<f64>,
}

impl SavitzkyGolay {
    /// The smoother fitting polynomials of degree `order` over `frame` samples.
    ///
    /// `frame` must be odd and larger than `order` (MATLAB's conditions).
    pub fn new(order: usize, frame: usize) -> Result<Self> {
        if frame.is_multiple_of(2) || frame <= order {
            return Err(Error::invalid(
                "Savitzky-Golay frame",
                frame,
                format!("the frame must be odd and longer than the order {order}"),
            ));
        }
        let m = order + 1;
        let half = (frame / 2) as f64;
        // V[i][j] = t_i^j with t = -half..half.
        let v: Vec<f64> = (0..frame)
            .flat_map(|i| (0..m).map(move |j| (i as f64 - half).powi(j as i32)))
            .collect();
        // Gauss–Jordan elimination of [VᵀV | Vᵀ] gives X = (VᵀV)⁻¹Vᵀ (m × frame).
        let width = m + frame;
        let mut a = vec![0.0; m * width];
        for r in 0..m {
            for c in 0..m {
                a[r * width + c] = (0..frame).map(|i| v[i * m + r] * v[i * m + c]).sum();
            }
            for i in 0..frame {
                a[r * width + m + i] = v[i * m + r];
            }
        }
        for col in 0..m {
            let pivot = (col..m)
                .max_by(|&p, &q| {
                    a[p * width + col]
                        .abs()
                        .total_cmp(&a[q * width + col].abs())
                })
                .unwrap_or(col);
            for c in 0..width {
                a.swap(col * width + c, pivot * width + c);
            }
            let p = a[col * width + col];
            for c in 0..width {
                a[col * width + c] /= p;
            }
            for r in (0..m).filter(|&r| r != col) {
                let f = a[r * width + col];
                for c in 0..width {
                    a[r * width + c] -= f * a[col * width + c];
                }
            }
        }
        let g = (0..frame)
            .flat_map(|i| {
                let (v, a) = (&v, &a);
                (0..frame).map(move |l| (0..m).map(|j| v[i * m + j] * a[j * width + m + l]).sum())
            })
            .collect();
        Ok(SavitzkyGolay { frame, g })
    }

    /// Frame length: the shortest signal that can be smoothed.
    pub fn frame(&self) -> usize {
        self.frame
    }

    /// The projection matrix, `frame × frame`, row-major: row `i` holds the weights of
    /// the frame's samples for the fitted value at position `i` (the centre row is the
    /// interior filter).
    pub fn coefficients(&self) -> &[f64] {
        &self.g
    }

    /// Smooths every column of the row-major matrix `x` (`x.len() / cols` rows of `cols`
    /// values) along its rows (MATLAB dimension 1) into `out`.
    ///
    /// # Panics
    /// If `out` and `x` differ in length, or there are fewer rows than [`Self::frame`].
    pub fn smooth_columns(&self, x: &[f64], cols: usize, out: &mut [f64]) {
        assert_eq!(x.len(), out.len(), "input and output sizes");
        let rows = x.len() / cols.max(1);
        let f = self.frame;
        assert!(rows >= f, "{rows} rows, fewer than the frame {f}");
        let half = f / 2;
        out.fill(0.0);
        for t in 0..rows {
            // Output row t: fit over rows start..start + f, evaluated at position p.
            let (start, p) = if t < half {
                (0, t)
            } else if t + half >= rows {
                (rows - f, t + f - rows)
            } else {
                (t - half, half)
            };
            let o = &mut out[t * cols..(t + 1) * cols];
            for (i, &g) in self.g[p * f..(p + 1) * f].iter().enumerate() {
                let r = &x[(start + i) * cols..(start + i + 1) * cols];
                for (o, v) in o.iter_mut().zip(r) {
                    *o += g * v;
                }
            }
        }
    }

    /// Smooths every row of the row-major matrix `x` (rows of `cols` values) along its
    /// columns (MATLAB dimension 2) into `out`.
    ///
    /// # Panics
    /// If `out` and `x` differ in length, or `cols` is below [`Self::frame`].
    pub fn smooth_rows(&self, x: &[f64], cols: usize, out: &mut [f64]) {
        assert_eq!(x.len(), out.len(), "input and output sizes");
        let f = self.frame;
        assert!(cols >= f, "{cols} columns, fewer than the frame {f}");
        let half = f / 2;
        for (xr, or) in x.chunks_exact(cols).zip(out.chunks_exact_mut(cols)) {
            for (t, o) in or.iter_mut().enumerate() {
                let (start, p) = if t < half {
                    (0, t)
                } else if t + half >= cols {
                    (cols - f, t + f - cols)
                } else {
                    (t - half, half)
                };
                let g = &self.g[p * f..(p + 1) * f];
                *o = g
                    .iter()
                    .zip(&xr[start..start + f])
                    .map(|(g, v)| g * v)
                    .sum();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The classical cubic five-point coefficients (Savitzky & Golay 1964, with the
    /// end-point rows of the least-squares fit).
    #[test]
    fn cubic_five_point_coefficients_are_the_textbook_ones() {
        let sg = SavitzkyGolay::new(3, 5).expect("valid");
        let want: [[f64; 5]; 5] = [
            [
                69.0 / 70.0,
                4.0 / 70.0,
                -6.0 / 70.0,
                4.0 / 70.0,
                -1.0 / 70.0,
            ],
            [
                2.0 / 35.0,
                27.0 / 35.0,
                12.0 / 35.0,
                -8.0 / 35.0,
                2.0 / 35.0,
            ],
            [
                -3.0 / 35.0,
                12.0 / 35.0,
                17.0 / 35.0,
                12.0 / 35.0,
                -3.0 / 35.0,
            ],
            [
                2.0 / 35.0,
                -8.0 / 35.0,
                12.0 / 35.0,
                27.0 / 35.0,
                2.0 / 35.0,
            ],
            [
                -1.0 / 70.0,
                4.0 / 70.0,
                -6.0 / 70.0,
                4.0 / 70.0,
                69.0 / 70.0,
            ],
        ];
        for (i, row) in want.iter().enumerate() {
            for (l, w) in row.iter().enumerate() {
                let got = sg.coefficients()[i * 5 + l];
                assert!((got - w).abs() < 1e-14, "G[{i}][{l}] = {got}, want {w}");
            }
        }
    }

    #[test]
    fn quadratic_seven_point_centre_row() {
        // (-2, 3, 6, 7, 6, 3, -2)/21
        let sg = SavitzkyGolay::new(2, 7).expect("valid");
        let want = [-2.0, 3.0, 6.0, 7.0, 6.0, 3.0, -2.0];
        for (l, w) in want.iter().enumerate() {
            assert!((sg.coefficients()[3 * 7 + l] - w / 21.0).abs() < 1e-14);
        }
    }

    /// A cubic is reproduced exactly, ends included; both directions agree.
    #[test]
    fn cubics_pass_unchanged_along_both_dimensions() {
        let sg = SavitzkyGolay::new(3, 5).expect("valid");
        let cubic = |t: f64| 0.5 - 2.0 * t + 0.25 * t * t - 0.125 * t * t * t;
        let (rows, cols) = (9, 6);
        // Column-wise cubics (down rows) and their transpose.
        let x: Vec<f64> = (0..rows * cols)
            .map(|i| cubic((i / cols) as f64) * (1.0 + (i % cols) as f64))
            .collect();
        let mut out = vec![0.0; x.len()];
        sg.smooth_columns(&x, cols, &mut out);
        for (o, v) in out.iter().zip(&x) {
            assert!((o - v).abs() < 1e-11 * v.abs().max(1.0), "{o} vs {v}");
        }
        let xt: Vec<f64> = (0..cols * rows)
            .map(|i| x[(i % rows) * cols + i / rows])
            .collect();
        let mut out_t = vec![0.0; xt.len()];
        sg.smooth_rows(&xt, rows, &mut out_t);
        for (i, o) in out_t.iter().enumerate() {
            assert!((o - out[(i % rows) * cols + i / rows]).abs() < 1e-12);
        }
    }

    #[test]
    fn interior_and_ends_use_their_rows() {
        let sg = SavitzkyGolay::new(3, 5).expect("valid");
        let x = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0];
        let mut out = [0.0; 7];
        sg.smooth_rows(&x, 7, &mut out);
        let g = sg.coefficients();
        // Sample 0 sees the impulse at frame position 0 of the first frame, sample 3
        // none, sample 6 the 2 at position 4 of the last frame.
        assert!((out[0] - g[0]).abs() < 1e-15 && (out[1] - g[5]).abs() < 1e-15);
        assert!((out[2] - g[10]).abs() < 1e-15 && out[3] == 0.0);
        assert!((out[6] - 2.0 * g[24]).abs() < 1e-15);
        assert!((out[4] - 2.0 * g[14]).abs() < 1e-15);
    }

    #[test]
    fn each_value_uses_the_first_last_or_centred_frame() {
        let sg = SavitzkyGolay::new(3, 5).expect("valid");
        assert_eq!(sg.frame(), 5);
        // an impulse at row 4 of 9 (and twice it in a second column): row t sees it at
        // position 4 − start of its frame, through the frame row p it is evaluated at;
        // rows 0-1 use the first frame (start 0), 7-8 the last (start 4), the others
        // the frame centred on them (p = 2)
        let mut x = vec![0.0; 18];
        x[8] = 1.0;
        x[9] = 2.0;
        let mut out = vec![f64::NAN; 18];
        sg.smooth_columns(&x, 2, &mut out);
        let g = sg.coefficients();
        let want = [4, 9, 14, 13, 12, 11, 10, 15, 20].map(|i| g[i]);
        for (t, w) in want.iter().enumerate() {
            assert!(
                (out[2 * t] - w).abs() < 1e-15,
                "row {t}: {} vs {w}",
                out[2 * t]
            );
            assert!(
                (out[2 * t + 1] - 2.0 * w).abs() < 1e-15,
                "row {t}, column 1"
            );
        }
        // the same along a row of 9
        let mut row = [0.0; 9];
        row[4] = 1.0;
        let mut out = [f64::NAN; 9];
        sg.smooth_rows(&row, 9, &mut out);
        for (t, w) in want.iter().enumerate() {
            assert!((out[t] - w).abs() < 1e-15, "column {t}: {} vs {w}", out[t]);
        }
    }

    #[test]
    fn bad_frames_are_errors() {
        assert!(SavitzkyGolay::new(3, 4).is_err());
        assert!(SavitzkyGolay::new(5, 5).is_err());
        assert!(SavitzkyGolay::new(0, 1).is_ok());
    }
}
