//! How a photo is prepared for the net: the size it sees the photo at, and
//! the normalisation of its levels (pipeline.md §8).

/// Per-channel mean subtracted from 0..255 RGB input.
pub const INPUT_MEAN: [f64; 3] = [123.68, 116.78, 103.94];
/// Divisor of the mean-subtracted input.
pub const INPUT_SCALE: f64 = 65.0;

/// The multiple of 32 nearest to `n` (at least 32): the side an image is
/// resized to before an encoder, so that every stride's grid divides it.
pub fn nearest_multiple_of_32(n: usize) -> i64 {
    ((n as f64 / 32.0).round() as i64).max(1) * 32
}

/// The size the net sees a `width x height` image at: shrunk to fit a
/// longer side of `side` (`None`: as it is; never enlarged), each side then
/// the nearest multiple of 32.
pub fn net_size(width: u32, height: u32, side: Option<u32>) -> (u32, u32) {
    let shrink = side.map_or(1.0, |side| {
        (side as f64 / width.max(height) as f64).min(1.0)
    });
    let fit = |n: u32| nearest_multiple_of_32((n as f64 * shrink).round() as usize) as u32;
    (fit(width), fit(height))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn photos_are_shrunk_to_the_side_and_rounded_to_32() {
        assert_eq!(net_size(1000, 750, Some(700)), (704, 512));
        assert_eq!(net_size(1000, 750, Some(256)), (256, 192));
        // Never enlarged, only rounded.
        assert_eq!(net_size(300, 200, Some(700)), (288, 192));
        assert_eq!(net_size(300, 200, None), (288, 192));
        // At least one cell of 32.
        assert_eq!(net_size(1000, 10, Some(128)), (128, 32));
    }
}
