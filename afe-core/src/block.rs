//! Time-major sample blocks.

use crate::huge_pages;

/// A time-major block of `f64` values: `frames()` rows of `width()` values each.
///
/// Processors write their new output of a chunk into a block; the block keeps its
/// capacity between chunks so that steady-state processing does not allocate.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Block {
    data: Vec<f64>,
    width: usize,
    /// Values at the start that are sealed: kept, but neither shown nor written (see
    /// [`Block::seal`]).
    sealed: usize,
}

impl Block {
    /// An empty block whose rows hold `width` values.
    pub fn new(width: usize) -> Self {
        Block {
            data: Vec::new(),
            width,
            sealed: 0,
        }
    }

    /// An empty block of `width`-value rows with room for `frames` rows.
    pub fn with_room(width: usize, frames: usize) -> Self {
        let mut b = Block::new(width);
        b.reserve_frames(frames);
        b
    }

    /// An empty block as wide as this one, with as much room.
    pub fn empty_like(&self) -> Self {
        let mut b = Block::new(self.width);
        b.grow(self.data.capacity());
        b
    }

    /// Rows it holds without reallocating.
    pub fn room(&self) -> usize {
        (self.data.capacity() - self.sealed)
            .checked_div(self.width)
            .unwrap_or(0)
    }

    /// A block holding `data` as rows of `width` values.
    ///
    /// # Panics
    /// If `data.len()` is not a multiple of `width`.
    pub fn from_vec(data: Vec<f64>, width: usize) -> Self {
        assert!(
            width > 0 && data.len().is_multiple_of(width),
            "block data length {} is not a multiple of its width {width}",
            data.len()
        );
        Block {
            data,
            width,
            sealed: 0,
        }
    }

    /// Values per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Number of rows (samples or frames).
    pub fn frames(&self) -> usize {
        self.shown().len().checked_div(self.width).unwrap_or(0)
    }

    /// True when the block holds no rows.
    pub fn is_empty(&self) -> bool {
        self.data.len() == self.sealed
    }

    /// All values, row after row.
    pub fn as_slice(&self) -> &[f64] {
        self.shown()
    }

    /// All values, row after row, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [f64] {
        &mut self.data[self.sealed..]
    }

    /// Row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.shown()[i * self.width..(i + 1) * self.width]
    }

    /// Iterator over the rows.
    pub fn rows(&self) -> std::slice::ChunksExact<'_, f64> {
        self.shown().chunks_exact(self.width.max(1))
    }

    /// Makes the block `frames` rows long, zero-filled, and returns its values.
    ///
    /// Does not allocate once the block has held that many values before.
    pub fn reset_to(&mut self, frames: usize) -> &mut [f64] {
        self.data.truncate(self.sealed);
        self.resize_to(frames)
    }

    /// Makes the block `frames` rows long without clearing it, for a caller that then
    /// writes every value: rows it held before keep stale values, new ones are zero.
    ///
    /// Does not allocate once the block has held that many values before.
    pub fn resize_to(&mut self, frames: usize) -> &mut [f64] {
        let len = self.sealed + frames * self.width;
        self.grow(len.saturating_sub(self.data.len()));
        self.data.resize(len, 0.0);
        &mut self.data[self.sealed..]
    }

    /// Appends the rows of `other`.
    ///
    /// # Panics
    /// If `other` has another width.
    pub fn extend_from(&mut self, other: &Block) {
        assert_eq!(self.width, other.width, "appending rows of another width");
        self.grow(other.as_slice().len());
        self.data.extend_from_slice(other.as_slice());
    }

    /// Appends `values`, whole rows of `width()` values each.
    ///
    /// # Panics
    /// If `values` does not hold whole rows.
    pub fn extend_from_slice(&mut self, values: &[f64]) {
        assert_eq!(
            values.len() % self.width.max(1),
            0,
            "appending part of a row"
        );
        self.grow(values.len());
        self.data.extend_from_slice(values);
    }

    /// Makes room for `frames` more rows, so that appending them does not reallocate.
    pub fn reserve_frames(&mut self, frames: usize) {
        self.grow(frames.saturating_mul(self.width));
    }

    /// As [`Block::reserve_frames`] for exactly `frames` more rows, returning the
    /// allocator's refusal instead of aborting the process (the buffers sized by a whole
    /// signal's length).
    pub fn try_reserve_frames(
        &mut self,
        frames: usize,
    ) -> Result<(), std::collections::TryReserveError> {
        huge_pages::try_reserve(&mut self.data, frames.saturating_mul(self.width))
    }

    /// Makes room for `values` more values. A new allocation of 4 MiB or more is advised
    /// to the kernel for huge pages before anything is written to it (see `huge_pages`).
    fn grow(&mut self, values: usize) {
        huge_pages::reserve(&mut self.data, values);
    }

    /// Removes the first `frames` rows shown (all of them if there are fewer), keeping the
    /// capacity: a bounded history drops its oldest rows.
    pub fn drop_front(&mut self, frames: usize) {
        let values = frames.saturating_mul(self.width).min(self.shown().len());
        self.data.drain(self.sealed..self.sealed + values);
    }

    /// Removes every row, keeping the capacity.
    pub fn clear(&mut self) {
        self.data.truncate(self.sealed);
    }

    /// Seals the rows it holds: they stay, after the rows sealed before, but the block
    /// shows and writes only rows that come after them, as if empty. A whole signal's
    /// output is so written chunk after chunk in place, where the processor writes its
    /// chunk, instead of being copied there (see [`Block::unseal`]).
    pub fn seal(&mut self) {
        self.sealed = self.data.len();
    }

    /// Shows every row again, the sealed ones first.
    pub fn unseal(&mut self) {
        self.sealed = 0;
    }

    /// The values shown: those after the sealed ones.
    fn shown(&self) -> &[f64] {
        &self.data[self.sealed..]
    }

    /// Consumes the block, returning its values row after row (sealed ones included).
    pub fn into_vec(self) -> Vec<f64> {
        self.data
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drop_front_removes_the_oldest_rows_only() {
        let mut b = Block::from_vec((0..12).map(f64::from).collect(), 3);
        b.drop_front(1);
        assert_eq!(
            b.as_slice(),
            &[3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0]
        );
        b.drop_front(10);
        assert!(b.is_empty());
        assert_eq!(b.width(), 3);
    }

    #[test]
    fn rows_are_contiguous_and_reset_keeps_capacity() {
        let mut b = Block::from_vec(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0], 3);
        assert_eq!(b.frames(), 2);
        assert_eq!(b.row(1), &[4.0, 5.0, 6.0]);
        let cap = b.data.capacity();
        assert_eq!(b.reset_to(1), &[0.0, 0.0, 0.0]);
        assert_eq!(b.data.capacity(), cap);
        assert_eq!(b.frames(), 1);
    }

    #[test]
    fn sealed_rows_stay_unseen_and_the_next_chunk_is_written_after_them() {
        let mut b = Block::with_room(2, 6);
        let room = b.room();
        b.resize_to(2).copy_from_slice(&[1.0, 2.0, 3.0, 4.0]);
        let at = b.as_slice().as_ptr();
        b.seal();
        assert!(b.is_empty() && b.frames() == 0 && b.rows().next().is_none());
        assert_eq!(b.room(), room - 2);
        // a processor's next chunk, as it writes it: cleared, then one row, then resized
        b.clear();
        b.reset_to(1).copy_from_slice(&[5.0, 6.0]);
        b.resize_to(2)[2..].copy_from_slice(&[7.0, 8.0]);
        assert_eq!(b.as_slice(), &[5.0, 6.0, 7.0, 8.0]);
        assert_eq!((b.frames(), b.row(1)), (2, &[7.0, 8.0][..]));
        b.as_mut_slice()[0] = 9.0;
        let mut copy = Block::new(2);
        copy.extend_from(&b);
        assert_eq!(copy.as_slice(), &[9.0, 6.0, 7.0, 8.0]);
        b.seal();
        b.unseal();
        assert_eq!(b.as_slice(), &[1.0, 2.0, 3.0, 4.0, 9.0, 6.0, 7.0, 8.0]);
        assert_eq!(b.as_slice().as_ptr(), at, "written in place, never moved");
        assert_eq!(b.frames(), 4);
    }

    #[test]
    fn blocks_keep_their_room_and_width() {
        let mut b = Block::with_room(4, 10);
        assert_eq!((b.width(), b.frames(), b.room()), (4, 0, 10));
        assert!(b.is_empty());
        let like = b.empty_like();
        assert_eq!((like.width(), like.room()), (4, 10));
        b.reserve_frames(20);
        assert!(b.room() >= 20);
        assert_eq!(Block::new(0).room(), 0);
        assert_eq!(Block::new(0).frames(), 0);
        b.extend_from(&Block::from_vec(vec![1.0; 8], 4));
        assert!(!b.is_empty());
        b.as_mut_slice()[5] = 7.0;
        assert_eq!(b.as_slice(), [1.0, 1.0, 1.0, 1.0, 1.0, 7.0, 1.0, 1.0]);
        // resizing keeps the rows it held and zero-fills new ones
        assert_eq!(
            b.resize_to(3)[4..],
            [1.0, 7.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0]
        );
        assert_eq!(b.rows().nth(1), Some(&[1.0, 7.0, 1.0, 1.0][..]));
        let room = b.room();
        b.clear();
        assert_eq!((b.frames(), b.room()), (0, room));
        assert_eq!(Block::from_vec(vec![2.0, 3.0], 1).into_vec(), [2.0, 3.0]);
    }

    #[test]
    #[should_panic(expected = "not a multiple of its width")]
    fn from_vec_refuses_a_partial_row() {
        let _ = Block::from_vec(vec![1.0; 5], 2);
    }

    #[test]
    #[should_panic(expected = "another width")]
    fn extend_from_refuses_another_width() {
        Block::new(2).extend_from(&Block::new(3));
    }
}
