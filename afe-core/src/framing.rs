//! The AFE framing rule (spec 00-overview §9): frames of `W` samples every `H` samples,
//! carried across chunks, with no padding and no flushing.
//!
//! A hop longer than the window (accepted, as by the AFE) leaves gaps between frames: a
//! gap that runs past the end of a chunk is skipped in the next one, so frame `j` still
//! covers `[j·H, j·H + W)`. (The MATLAB AFE forgets such a gap at a chunk boundary, so
//! its chunked output there depends on the chunking; its one-call output is this one.)

use std::ops::Range;

use crate::lanes::vector_start;

/// The rows of a time-major signal still needed by coming frames.
///
/// Frame `j` of the stream always covers stream rows `[j·H, j·H + W)`, whatever the
/// chunking, which makes every framed processor chunk-invariant. Frames are read over
/// the kept rows followed by the new chunk, which is borrowed, not copied: only the rows
/// that later frames still need are kept, at [`FrameBuffer::advance`].
///
/// A buffer may frame a range of the input's columns only (see [`FrameBuffer::columns`]):
/// a part of a split processor then keeps and copies its own channels alone, and its join
/// only counts rows (see [`FrameBuffer::count_only`], [`FrameBuffer::joined`]).
#[derive(Debug, PartialEq)]
pub struct FrameBuffer {
    /// Values per input row.
    width: usize,
    /// The columns framed and kept.
    columns: Range<usize>,
    window: usize,
    hop: usize,
    /// Rows from the start of the next frame on, `columns.len()` values each.
    kept: Vec<f64>,
    /// Number of rows kept (held in `kept` unless the buffer only counts).
    rows: usize,
    /// Rows of coming input to drop before the next frame starts (a gap between frames
    /// when the hop is longer than the window; `kept` is empty while it is non-zero).
    skip: usize,
}

/// One frame: rows kept from earlier chunks (`head`, `width` values each), then rows of
/// the new chunk (`tail`, whole input rows of `stride` values, whose columns `offset..`
/// `offset + width` are the frame's). Over all columns, `stride == width` and `offset == 0`.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    /// The frame's first rows, from earlier chunks.
    pub head: &'a [f64],
    /// The frame's remaining rows, from the new chunk.
    pub tail: &'a [f64],
    width: usize,
    stride: usize,
    offset: usize,
}

impl<'a> Frame<'a> {
    /// The frame's rows in time order, `width` values each.
    pub fn rows(&self) -> impl Iterator<Item = &'a [f64]> {
        let (head, tail) = (self.head, self.tail);
        let (width, offset) = (self.width, self.offset);
        head.chunks_exact(width).chain(
            tail.chunks_exact(self.stride)
                .map(move |r| &r[offset..offset + width]),
        )
    }

    /// `head` and `tail`, each with its row length and the index in its rows of the
    /// frame's first column (for loops that read whole rows without slicing each).
    pub fn segments(&self) -> [(&'a [f64], usize, usize); 2] {
        [
            (self.head, self.width, 0),
            (self.tail, self.stride, self.offset),
        ]
    }

    /// Values per row of the frame.
    pub fn width(&self) -> usize {
        self.width
    }

    /// The input column of the frame's first column.
    pub fn first_column(&self) -> usize {
        self.offset
    }

    /// Writes the frame's rows, row `t` times `win[t]`, into `cols` as columns
    /// (`[column][time]`, `win.len()` values each, one per row), and where `peaks` is
    /// given (one per column) each column's largest windowed value into it, and where
    /// `troughs` is given its smallest (NaN ignored, as MATLAB's `max` and `min`). Tiles
    /// of [`TILE`] rows by [`TILE`] columns go through registers, so that each column
    /// takes a cache line per store; the last tile of a row ends at its last column (a
    /// column in two tiles gets its values twice).
    /// Inlined so that its loops get the caller's vector width.
    #[inline(always)]
    pub fn window_columns(
        &self,
        win: &[f64],
        cols: &mut [f64],
        mut peaks: Option<&mut [f64]>,
        mut troughs: Option<&mut [f64]>,
    ) {
        let (nc, w) = (self.width, win.len());
        for extremes in [peaks.as_deref_mut(), troughs.as_deref_mut()]
            .into_iter()
            .flatten()
        {
            extremes.fill(f64::NAN);
        }
        let tiles = if nc >= TILE { nc.div_ceil(TILE) } else { 0 };
        let mut n0 = 0;
        for (part, stride, at) in self.segments() {
            let rows = part.len() / stride.max(1);
            let whole = if tiles > 0 { rows - rows % TILE } else { 0 };
            for t0 in (0..whole).step_by(TILE) {
                let mut wins = [0.0; TILE];
                wins.copy_from_slice(&win[n0 + t0..n0 + t0 + TILE]);
                for c0 in (0..tiles).map(|g| vector_start(g, TILE, nc)) {
                    let mut block = [[0.0; TILE]; TILE];
                    for (i, (row, wt)) in block.iter_mut().zip(wins).enumerate() {
                        let start = (t0 + i) * stride + at + c0;
                        for (b, v) in row.iter_mut().zip(&part[start..start + TILE]) {
                            *b = wt * v;
                        }
                    }
                    if let Some(p) = peaks.as_deref_mut() {
                        for row in &block {
                            for (p, v) in p[c0..c0 + TILE].iter_mut().zip(row) {
                                *p = p.max(*v);
                            }
                        }
                    }
                    if let Some(low) = troughs.as_deref_mut() {
                        for row in &block {
                            for (l, v) in low[c0..c0 + TILE].iter_mut().zip(row) {
                                *l = l.min(*v);
                            }
                        }
                    }
                    let mut transposed = [[0.0; TILE]; TILE];
                    for (i, row) in block.iter().enumerate() {
                        for (col, v) in transposed.iter_mut().zip(row) {
                            col[i] = *v;
                        }
                    }
                    for (j, col) in transposed.iter().enumerate() {
                        let start = (c0 + j) * w + n0 + t0;
                        cols[start..start + TILE].copy_from_slice(col);
                    }
                }
            }
            for t in whole..rows {
                let row = &part[t * stride + at..t * stride + at + nc];
                for (c, v) in row.iter().enumerate() {
                    let x = win[n0 + t] * v;
                    cols[c * w + n0 + t] = x;
                    if let Some(p) = peaks.as_deref_mut() {
                        p[c] = p[c].max(x);
                    }
                    if let Some(low) = troughs.as_deref_mut() {
                        low[c] = low[c].min(x);
                    }
                }
            }
            n0 += rows;
        }
    }
}

/// Rows and columns of a tile of [`Frame::window_columns`]: a cache line of values.
pub const TILE: usize = 8;

/// A copy with as much room as the original, so that a copy made before the audio
/// starts (a split processor's part) never grows on the audio path.
impl Clone for FrameBuffer {
    fn clone(&self) -> Self {
        let mut kept = Vec::with_capacity(self.kept.capacity());
        kept.extend_from_slice(&self.kept);
        FrameBuffer {
            kept,
            columns: self.columns.clone(),
            ..*self
        }
    }
}

impl FrameBuffer {
    /// A buffer for rows of `width` values, frames of `window` rows every `hop` rows.
    ///
    /// # Panics
    /// If `hop` is zero.
    pub fn new(width: usize, window: usize, hop: usize) -> Self {
        assert!(hop > 0, "invalid framing {window}/{hop}");
        FrameBuffer {
            width,
            columns: 0..width,
            window,
            hop,
            kept: Vec::with_capacity(window * width),
            rows: 0,
            skip: 0,
        }
    }

    /// A copy that frames and keeps only `columns` (a non-empty range within this
    /// buffer's), with its kept rows narrowed and as much room per column.
    ///
    /// # Panics
    /// If `columns` is empty or not within this buffer's columns.
    pub fn columns(&self, columns: Range<usize>) -> Self {
        assert!(
            !columns.is_empty()
                && self.columns.start <= columns.start
                && columns.end <= self.columns.end,
            "columns {columns:?} not within {:?}",
            self.columns
        );
        let old = self.columns.len();
        let (from, to) = (
            columns.start - self.columns.start,
            columns.end - self.columns.start,
        );
        let mut kept = Vec::with_capacity(self.kept.capacity() / old * columns.len());
        for row in self.kept.chunks_exact(old) {
            kept.extend_from_slice(&row[from..to]);
        }
        FrameBuffer {
            kept,
            columns,
            ..*self
        }
    }

    /// Stops keeping values, counting rows only (what the join of a split processor needs
    /// to know how many frames each chunk completes). Allocates and frees nothing.
    pub fn count_only(&mut self) {
        self.kept.clear();
        self.columns = self.columns.start..self.columns.start;
    }

    /// The buffer over all columns that `parts` (consecutive column ranges of one
    /// buffer, in order, at the same point of the stream) make together, with the room
    /// of them all.
    ///
    /// # Panics
    /// If the parts are not consecutive ranges of one stream's buffer at one point.
    pub fn joined(parts: &[&FrameBuffer]) -> Self {
        let first = parts.first().expect("at least one part");
        let mut columns = first.columns.start..first.columns.start;
        for p in parts {
            assert!(
                p.columns.start == columns.end
                    && (p.width, p.window, p.hop, p.rows, p.skip)
                        == (first.width, first.window, first.hop, first.rows, first.skip),
                "parts of different buffers"
            );
            columns.end = p.columns.end;
        }
        let room = parts.iter().map(|p| p.kept.capacity()).sum();
        let mut kept = Vec::with_capacity(room);
        for r in 0..first.rows {
            for p in parts {
                let w = p.columns.len();
                kept.extend_from_slice(&p.kept[r * w..(r + 1) * w]);
            }
        }
        FrameBuffer {
            kept,
            columns,
            ..**first
        }
    }

    /// Appends the framed columns of whole input rows to the kept rows.
    fn keep(&mut self, rows: &[f64]) {
        self.rows += rows.len() / self.width.max(1);
        if self.columns.len() == self.width {
            self.kept.extend_from_slice(rows);
        } else if !self.columns.is_empty() {
            for row in rows.chunks_exact(self.width) {
                self.kept.extend_from_slice(&row[self.columns.clone()]);
            }
        }
    }

    /// `input` after the rows still to be skipped.
    fn fresh<'a>(&self, input: &'a [f64]) -> &'a [f64] {
        &input[(self.skip * self.width).min(input.len())..]
    }

    /// Number of complete frames over the kept rows followed by `input`.
    pub fn available(&self, input: &[f64]) -> usize {
        let input = self.fresh(input);
        let n = self.rows + input.len() / self.width.max(1);
        if n < self.window {
            0
        } else {
            (n - self.window) / self.hop + 1
        }
    }

    /// Frame `k` (counted from the next frame) over the kept rows followed by `input`;
    /// `k` must be below [`FrameBuffer::available`].
    pub fn frame<'a>(&'a self, input: &'a [f64], k: usize) -> Frame<'a> {
        let input = self.fresh(input);
        let (kept, width, cw) = (self.rows, self.width, self.columns.len());
        let start = k * self.hop;
        let end = start + self.window;
        Frame {
            head: &self.kept[start.min(kept) * cw..end.min(kept) * cw],
            tail: &input[start.saturating_sub(kept) * width..(end - kept.min(end)) * width],
            width: cw,
            stride: width,
            offset: self.columns.start,
        }
    }

    /// Drops `frames` frames and keeps the rows after them, from `input` too; `input`
    /// is the chunk just framed.
    pub fn advance(&mut self, input: &[f64], frames: usize) {
        let fresh = self.fresh(input);
        let width = self.width.max(1);
        self.skip -= (input.len() - fresh.len()) / width;
        let next = frames * self.hop;
        let kept = self.rows;
        if next <= kept {
            self.kept.drain(..next * self.columns.len());
            self.rows -= next;
            self.keep(fresh);
        } else {
            self.kept.clear();
            self.rows = 0;
            let drop = (next - kept) * width;
            match fresh.get(drop..) {
                Some(rest) => self.keep(rest),
                None => self.skip = (drop - fresh.len()) / width,
            }
        }
    }

    /// Forgets the kept rows (a new stream starts).
    pub fn reset(&mut self) {
        self.kept.clear();
        self.rows = 0;
        self.skip = 0;
    }

    /// Window length in rows.
    pub fn window(&self) -> usize {
        self.window
    }

    /// Values per row.
    pub fn width(&self) -> usize {
        self.width
    }
}

/// Window length in samples, `2·round(w_size_s·fs/2)`, evaluated in that order.
pub fn window_samples(w_size_s: f64, fs: f64) -> usize {
    (2.0 * (w_size_s * fs / 2.0).round()).max(0.0) as usize
}

/// Hop length in samples, `round(h_size_s·fs)`.
pub fn hop_samples(h_size_s: f64, fs: f64) -> usize {
    (h_size_s * fs).round().max(0.0) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    fn collect(frame: Frame<'_>) -> Vec<f64> {
        frame.rows().flatten().copied().collect()
    }

    /// The tiled transposition gives each column's windowed values, peak and trough, as a
    /// plain loop over the rows does: for fewer columns than a tile, one tile, tiles
    /// that overlap at the end, frames split between kept rows and a chunk, rows left
    /// over by the tiles, a frame over part of the columns and NaN in the input.
    #[test]
    fn windowed_columns_and_peaks_equal_the_plain_loops() {
        for (width, cols) in [(3, 0..3), (8, 0..8), (31, 0..31), (31, 5..19), (20, 0..20)] {
            let (window, hop) = (37, 11);
            let mut x: Vec<f64> = (0..width * 120)
                .map(|i| ((i * 7919) % 1013) as f64 - 500.0)
                .collect();
            x[width * 50 + cols.start] = f64::NAN;
            let win: Vec<f64> = (0..window).map(|t| 0.5 + t as f64 / 40.0).collect();
            let mut fb = FrameBuffer::new(width, window, hop).columns(cols.clone());
            let nc = cols.len();
            for part in x.chunks(width * 17) {
                for k in 0..fb.available(part) {
                    let frame = fb.frame(part, k);
                    let mut want = vec![0.0; nc * window];
                    let (mut want_peaks, mut want_troughs) =
                        (vec![f64::NAN; nc], vec![f64::NAN; nc]);
                    for (t, row) in frame.rows().enumerate() {
                        for (c, v) in row.iter().enumerate() {
                            want[c * window + t] = win[t] * v;
                            want_peaks[c] = want_peaks[c].max(win[t] * v);
                            want_troughs[c] = want_troughs[c].min(win[t] * v);
                        }
                    }
                    let mut got = vec![f64::INFINITY; nc * window];
                    let (mut peaks, mut troughs) = (vec![0.0; nc], vec![0.0; nc]);
                    frame.window_columns(&win, &mut got, Some(&mut peaks), Some(&mut troughs));
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&got), bits(&want), "{width} wide, {cols:?}");
                    assert_eq!(bits(&peaks), bits(&want_peaks), "{width} wide, {cols:?}");
                    assert_eq!(
                        bits(&troughs),
                        bits(&want_troughs),
                        "{width} wide, {cols:?}"
                    );
                    let mut alone = vec![f64::INFINITY; nc * window];
                    frame.window_columns(&win, &mut alone, None, None);
                    assert_eq!(bits(&alone), bits(&want));
                }
                let n = fb.available(part);
                fb.advance(part, n);
            }
        }
    }

    #[test]
    fn frames_follow_the_stream_whatever_the_chunking() {
        let x: Vec<f64> = (0..46).map(f64::from).collect();
        let one = FrameBuffer::new(2, 6, 4);
        let n = one.available(&x);
        assert_eq!(n, (23 - 6) / 4 + 1);
        let whole: Vec<Vec<f64>> = (0..n).map(|k| collect(one.frame(&x, k))).collect();
        for chunk in [1, 3, 5, 12, 40] {
            let mut chunked = Vec::new();
            let mut fb = FrameBuffer::new(2, 6, 4);
            for part in x.chunks(2 * chunk) {
                let m = fb.available(part);
                chunked.extend((0..m).map(|k| collect(fb.frame(part, k))));
                fb.advance(part, m);
            }
            assert_eq!(whole, chunked, "chunks of {chunk} rows");
        }
        assert_eq!(whole[1], (8..20).map(f64::from).collect::<Vec<_>>());
    }

    #[test]
    fn column_ranges_frame_their_columns_and_join_back_and_a_counter_keeps_count() {
        // 5 columns; frames of 6 rows every 4 (overlapping) and of 3 every 7 (gaps)
        let x: Vec<f64> = (0..5 * 61).map(|i| i as f64).collect();
        for (window, hop) in [(6, 4), (3, 7)] {
            for cols in [1..4, 0..5, 4..5] {
                for chunk in [1, 2, 5, 13, 30] {
                    let mut full = FrameBuffer::new(5, window, hop);
                    let mut narrow: Option<FrameBuffer> = None;
                    let mut counter: Option<FrameBuffer> = None;
                    for (k, part) in x.chunks(5 * chunk).enumerate() {
                        // narrowed after the first chunk, from the rows it kept; a copy
                        // that only counts from then on
                        if k == 1 {
                            // narrowing twice is narrowing once
                            let last = cols.end - 1..cols.end;
                            assert_eq!(
                                full.columns(cols.clone()).columns(last.clone()),
                                full.columns(last)
                            );
                            narrow = Some(full.columns(cols.clone()));
                            let mut c = full.clone();
                            c.count_only();
                            counter = Some(c);
                        }
                        let m = full.available(part);
                        if let Some(c) = counter.as_mut() {
                            assert_eq!(c.available(part), m);
                            c.advance(part, m);
                            assert!(c.kept.is_empty());
                        }
                        if let Some(fb) = narrow.as_mut() {
                            assert_eq!(fb.available(part), m);
                            for j in 0..m {
                                let want: Vec<f64> = full
                                    .frame(part, j)
                                    .rows()
                                    .flat_map(|r| r[cols.clone()].to_vec())
                                    .collect();
                                let frame = fb.frame(part, j);
                                assert_eq!(frame.width(), cols.len());
                                assert_eq!(frame.first_column(), cols.start);
                                assert_eq!(collect(frame), want, "{cols:?}, chunk {chunk}");
                                let mut from_segments = Vec::new();
                                for (values, stride, at) in frame.segments() {
                                    for row in values.chunks_exact(stride) {
                                        from_segments.extend_from_slice(&row[at..at + cols.len()]);
                                    }
                                }
                                assert_eq!(from_segments, want);
                            }
                            fb.advance(part, m);
                        }
                        full.advance(part, m);
                    }
                    // with buffers over the other columns, the whole buffer again
                    let rest: Vec<Range<usize>> = [0..cols.start, cols.end..5]
                        .into_iter()
                        .filter(|r| !r.is_empty())
                        .collect();
                    if let Some(narrow) = narrow {
                        let mut parts: Vec<FrameBuffer> =
                            rest.iter().map(|r| full.columns(r.clone())).collect();
                        parts.push(narrow);
                        parts.sort_by_key(|p| p.columns.start);
                        let refs: Vec<&FrameBuffer> = parts.iter().collect();
                        assert_eq!(FrameBuffer::joined(&refs), full, "{cols:?}, chunk {chunk}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_hop_longer_than_the_window_skips_the_gaps_across_chunks() {
        // one and three values per row: the gap is counted in rows, not values
        for width in [1, 3] {
            let x: Vec<f64> = (0..61 * width).map(|i| i as f64).collect();
            let one = FrameBuffer::new(width, 3, 7);
            let n = one.available(&x);
            assert_eq!(n, (61 - 3) / 7 + 1);
            let whole: Vec<Vec<f64>> = (0..n).map(|k| collect(one.frame(&x, k))).collect();
            let third: Vec<f64> = (14 * width..17 * width).map(|i| i as f64).collect();
            assert_eq!(whole[2], third);
            for chunk in [1, 2, 3, 4, 6, 9, 61] {
                let mut chunked = Vec::new();
                let mut fb = FrameBuffer::new(width, 3, 7);
                for part in x.chunks(chunk * width) {
                    let m = fb.available(part);
                    chunked.extend((0..m).map(|k| collect(fb.frame(part, k))));
                    fb.advance(part, m);
                }
                assert_eq!(whole, chunked, "chunks of {chunk} rows of {width}");
            }
        }
    }

    #[test]
    fn only_rows_of_coming_frames_are_kept() {
        let mut fb = FrameBuffer::new(1, 6, 2);
        let x: Vec<f64> = (0..100).map(f64::from).collect();
        let n = fb.available(&x);
        fb.advance(&x, n);
        // 48 frames end at row 100; the next starts at row 96.
        assert_eq!(fb.kept, vec![96.0, 97.0, 98.0, 99.0]);
    }

    #[test]
    fn reset_forgets_the_kept_rows_and_the_gap() {
        let x: Vec<f64> = (0..20).map(f64::from).collect();
        let mut fb = FrameBuffer::new(1, 4, 6);
        let n = fb.available(&x[..9]);
        fb.advance(&x[..9], n);
        fb.reset();
        let fresh = FrameBuffer::new(1, 4, 6);
        assert_eq!(fb, fresh);
        assert_eq!(collect(fb.frame(&x, 0)), vec![0.0, 1.0, 2.0, 3.0]);
    }

    #[test]
    fn short_first_chunk_gives_no_frame() {
        let fb = FrameBuffer::new(2, 10, 4);
        assert_eq!((fb.width(), fb.window()), (2, 10));
        assert_eq!(fb.available(&[0.0; 2 * 5]), 0);
        assert_eq!(fb.available(&[0.0; 2 * 9]), 0);
        // exactly one window: one frame
        assert_eq!(fb.available(&[0.0; 2 * 10]), 1);
    }

    #[test]
    fn lengths_use_matlab_rounding() {
        assert_eq!(window_samples(0.02, 44100.0), 882);
        assert_eq!(hop_samples(0.01, 22050.0), 221);
        assert_eq!(window_samples(0.02, 22050.0), 442);
    }
}
