//! A single-channel float image: the type of soft maps, weights and channels.

/// A row-major single-channel `f32` image. Soft maps and weights live in `[0, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` values, row by row.
    pub data: Vec<f32>,
}

impl Plane {
    /// A plane filled with `value`.
    pub fn new(width: usize, height: usize, value: f32) -> Self {
        Self {
            width,
            height,
            data: vec![value; width * height],
        }
    }

    /// Wraps existing row-major data; `data.len()` must be `width * height`.
    pub fn from_vec(width: usize, height: usize, data: Vec<f32>) -> Self {
        assert_eq!(
            data.len(),
            width * height,
            "plane data has the wrong length"
        );
        Self {
            width,
            height,
            data,
        }
    }

    /// The value at column `x`, row `y`.
    pub fn get(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Sum of all values, accumulated in `f64`.
    pub fn sum(&self) -> f64 {
        self.data.iter().map(|&v| v as f64).sum()
    }

    /// Count of values strictly greater than `t`.
    pub fn count_above(&self, t: f32) -> usize {
        self.data.iter().filter(|&&v| v > t).count()
    }

    /// Count of values less than or equal to `t`.
    pub fn count_at_or_below(&self, t: f32) -> usize {
        self.len() - self.count_above(t)
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// True when the plane has no pixels.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Values in `[0, 1]` to 8-bit, rounded and clamped.
    pub fn to_u8(&self) -> Vec<u8> {
        self.data.iter().map(|&v| unit_to_u8(v)).collect()
    }
}

/// Maps a value in `[0, 1]` to `0..=255`, rounding to nearest and clamping.
pub fn unit_to_u8(v: f32) -> u8 {
    round_to_u8(v * 255.0)
}

/// Rounds a value on the 0..255 scale to the nearest level (halves up),
/// clamped to `0..=255` (NaN gives 0). Adding a half and truncating is
/// exact for these values and avoids a `round` call the baseline x86-64
/// target cannot inline.
#[inline]
pub fn round_to_u8(v: f32) -> u8 {
    // `max` drops NaN, so the value is in 0..=255 and truncates with one
    // instruction that vectorises (`as` would check every lane for NaN and
    // overflow, which keeps the loops scalar).
    #[allow(clippy::manual_clamp)] // `clamp` would keep NaN.
    let clamped = (v + 0.5).max(0.0).min(255.0);
    // SAFETY: `clamped` is finite and within 0..=255, so it fits `i32`.
    unsafe { clamped.to_int_unchecked::<i32>() as u8 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_split_the_plane() {
        let p = Plane::from_vec(2, 2, vec![0.1, 0.5, 0.5, 0.9]);
        assert_eq!(p.count_above(0.5), 1);
        assert_eq!(p.count_at_or_below(0.5), 3);
        assert!((p.sum() - 2.0).abs() < 1e-6);
        assert_eq!(p.to_u8(), vec![26, 128, 128, 230]);
        let rounded = [-3.0, -0.6, 0.49, 0.5, 2.5, 254.5, 300.0, f32::NAN].map(round_to_u8);
        assert_eq!(rounded, [0, 0, 0, 1, 3, 255, 255, 0]);
        // Equal to rounding half up and saturating, on a dense sweep.
        for i in -4000..=140_000 {
            let v = i as f32 / 512.0;
            let want = (v + 0.5).floor().clamp(0.0, 255.0) as u8;
            assert_eq!(round_to_u8(v), want, "{v}");
        }
        assert_eq!(round_to_u8(f32::INFINITY), 255);
        assert_eq!(round_to_u8(f32::NEG_INFINITY), 0);
    }
}
