//! The fuzzy threshold ("colour ramp") that turns a channel into a soft map.

use serde::{Deserialize, Serialize};

/// A ramp: 0 at or below `low`, 1 above `high`, linear in between. With
/// `low == high` it is a binary threshold (1 strictly above, 0 otherwise).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ramp {
    /// Values at or below this map to 0.
    pub low: f32,
    /// Values above this map to 1.
    pub high: f32,
}

impl Ramp {
    /// The ramp's value at `v`.
    #[inline]
    pub fn apply(&self, v: f32) -> f32 {
        if v > self.high {
            1.0
        } else if v <= self.low {
            0.0
        } else {
            (v - self.low) / (self.high - self.low)
        }
    }

    /// Applies the ramp to every value of `data` in place (branch-free, so
    /// it vectorises); equal to [`Ramp::apply`] on each value.
    pub fn apply_all(&self, data: &mut [f32]) {
        if self.is_binary() {
            let t = self.high;
            data.iter_mut()
                .for_each(|v| *v = if *v > t { 1.0 } else { 0.0 });
        } else {
            let (low, scale) = (self.low, 1.0 / (self.high - self.low));
            data.iter_mut()
                .for_each(|v| *v = ((*v - low) * scale).clamp(0.0, 1.0));
        }
    }

    /// True for a binary (hard) threshold.
    pub fn is_binary(&self) -> bool {
        self.low >= self.high
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_is_zero_below_one_above_linear_between() {
        let r = Ramp {
            low: 0.2,
            high: 0.6,
        };
        assert_eq!(r.apply(0.1), 0.0);
        assert_eq!(r.apply(0.2), 0.0);
        assert!((r.apply(0.4) - 0.5).abs() < 1e-6);
        assert_eq!(r.apply(0.6), 1.0);
        assert_eq!(r.apply(0.61), 1.0);
        let mut values = vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.61];
        let expected: Vec<f32> = values.iter().map(|&v| r.apply(v)).collect();
        r.apply_all(&mut values);
        for (a, b) in values.iter().zip(&expected) {
            assert!((a - b).abs() < 1e-6);
        }
    }

    #[test]
    fn equal_thresholds_give_a_binary_map() {
        let r = Ramp {
            low: 0.5,
            high: 0.5,
        };
        assert!(r.is_binary());
        assert_eq!(r.apply(0.5), 0.0);
        assert_eq!(r.apply(0.5001), 1.0);
    }
}
