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

    /// True when the sum of all values reaches `mass` (stops as soon as it does).
    pub fn mass_at_least(&self, mass: f64) -> bool {
        let mut total = 0.0f64;
        for chunk in self.data.chunks(4096) {
            total += chunk.iter().map(|&v| v as f64).sum::<f64>();
            if total >= mass {
                return true;
            }
        }
        total >= mass
    }

    /// The largest value (`0` for an empty plane).
    pub fn max(&self) -> f32 {
        self.data.iter().copied().fold(0.0, f32::max)
    }

    /// Count of values strictly greater than `t`.
    pub fn count_above(&self, t: f32) -> usize {
        count_above(&self.data, t)
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

    /// Multiplies every value by `k` in place.
    pub fn scale(&mut self, k: f32) {
        self.data.iter_mut().for_each(|v| *v *= k);
    }

    /// Divides every value by the largest one (no change when it is 0).
    pub fn normalise_by_max(&mut self) {
        let max = self.max();
        if max > 0.0 {
            self.scale(1.0 / max);
        }
    }

    /// Values in `[0, 1]` to 8-bit, rounded and clamped.
    pub fn to_u8(&self) -> Vec<u8> {
        self.data.iter().map(|&v| unit_to_u8(v)).collect()
    }
}

/// Count of `values` strictly greater than `t` (AVX2 when the CPU has it).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn count_above(values: &[f32], t: f32) -> usize {
    values.iter().filter(|&&v| v > t).count()
}

/// Maps a value in `[0, 1]` to `0..=255`, rounding to nearest and clamping.
pub fn unit_to_u8(v: f32) -> u8 {
    (v * 255.0).round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_split_the_plane() {
        let p = Plane::from_vec(2, 2, vec![0.1, 0.5, 0.5, 0.9]);
        assert_eq!(p.count_above(0.5), 1);
        assert_eq!(p.count_at_or_below(0.5), 3);
        assert_eq!(p.max(), 0.9);
        assert!((p.sum() - 2.0).abs() < 1e-6);
        assert_eq!(p.to_u8(), vec![26, 128, 128, 230]);
        assert!(p.mass_at_least(2.0 - 1e-6));
        assert!(!p.mass_at_least(2.1));
        let mut q = p.clone();
        q.normalise_by_max();
        assert_eq!(q.max(), 1.0);
        assert!((q.data[0] - 0.1 / 0.9).abs() < 1e-6);
    }
}
