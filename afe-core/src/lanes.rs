//! Channels in SIMD vectors without a scalar remainder.

/// First channel of vector `v` when `len` channels go `width` to a vector: `v·width`,
/// except that the last vector ends at the last channel, overlapping its neighbour when
/// `len` is not a multiple of `width`. An overlapped channel then sits in two lanes that
/// compute the same values; fewer than `width` channels make one vector at 0.
#[inline]
pub fn vector_start(v: usize, width: usize, len: usize) -> usize {
    (v * width).min(len.saturating_sub(width))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_vector_ends_at_the_last_channel() {
        let starts: Vec<usize> = (0..4).map(|v| vector_start(v, 8, 31)).collect();
        assert_eq!(starts, [0, 8, 16, 23]);
        assert_eq!(vector_start(0, 8, 5), 0);
        assert_eq!(vector_start(1, 8, 16), 8);
    }
}
