//! Random numbers and the warps that turn them into directions.
//!
//! Every pixel owns a PCG32 stream seeded from (scene seed, pixel index), so
//! an image is the same whatever the thread count or the order of rows.

use crate::math::Vec3;
use std::f32::consts::PI;

/// PCG32 (O'Neill 2014, XSH-RR output): small, fast, statistically good.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const PCG_MULT: u64 = 6364136223846793005;

/// SplitMix64 finaliser: spreads consecutive seeds over the state space.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

impl Pcg32 {
    /// A generator for stream `stream` of `seed`.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Pcg32 {
            state: 0,
            inc: (mix64(stream ^ 0x9e3779b97f4a7c15) << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(mix64(seed));
        rng.next_u32();
        rng
    }

    /// The next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// A uniform float in `[0, 1)`.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Two uniform floats in `[0, 1)`.
    #[inline]
    pub fn next_2d(&mut self) -> [f32; 2] {
        [self.next_f32(), self.next_f32()]
    }
}

/// The stratum of sample `index` out of `count` on a `n x n` grid (n the
/// integer square root of `count`, rounded up), jittered by `u`: the first
/// `n * n` samples of a pixel cover it evenly.
pub fn stratified_2d(index: u32, count: u32, u: [f32; 2]) -> [f32; 2] {
    let n = (count as f32).sqrt().ceil().max(1.0) as u32;
    let cell = index % (n * n);
    let (cx, cy) = (cell % n, cell / n);
    [(cx as f32 + u[0]) / n as f32, (cy as f32 + u[1]) / n as f32]
}

/// A cosine-weighted direction about +z (Malley's method via the
/// concentric disk); its density is `cos(theta) / pi`.
pub fn cosine_hemisphere(u: [f32; 2]) -> Vec3 {
    let [dx, dy] = concentric_disk(u);
    let z = (1.0 - dx * dx - dy * dy).max(0.0).sqrt();
    Vec3::new(dx, dy, z)
}

/// A point on the unit disk, area-preserving (Shirley and Chiu 1997).
pub fn concentric_disk(u: [f32; 2]) -> [f32; 2] {
    let (a, b) = (2.0 * u[0] - 1.0, 2.0 * u[1] - 1.0);
    if a == 0.0 && b == 0.0 {
        return [0.0, 0.0];
    }
    let (r, theta) = if a.abs() > b.abs() {
        (a, PI / 4.0 * (b / a))
    } else {
        (b, PI / 2.0 - PI / 4.0 * (a / b))
    };
    [r * theta.cos(), r * theta.sin()]
}

/// A uniformly distributed direction on the sphere (density `1 / 4pi`).
pub fn uniform_sphere(u: [f32; 2]) -> Vec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// The power heuristic (beta = 2) weight of a strategy with density `a`
/// against one with density `b` (Veach 1997).
#[inline]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// A table to draw an index with probability proportional to given weights,
/// and to ask that probability back.
#[derive(Clone, Debug)]
pub struct Distribution1d {
    /// Cumulative weights, normalised: `cdf[0] = 0`, `cdf[n] = 1`.
    cdf: Vec<f32>,
    /// The weights' sum before normalising.
    total: f32,
}

impl Distribution1d {
    /// From non-negative weights; all-zero weights become uniform.
    pub fn new(weights: &[f32]) -> Self {
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        let mut acc = 0f64;
        cdf.push(0.0);
        for &w in weights {
            acc += w.max(0.0) as f64;
            cdf.push(acc as f32);
        }
        let total = acc as f32;
        let n = weights.len().max(1) as f32;
        for (i, c) in cdf.iter_mut().enumerate() {
            *c = if total > 0.0 {
                *c / total
            } else {
                i as f32 / n
            };
        }
        Distribution1d { cdf, total }
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.cdf.len() - 1
    }

    /// Whether there are no entries.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The sum of the weights.
    pub fn total(&self) -> f32 {
        self.total
    }

    /// Probability of index `i`.
    pub fn probability(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }

    /// Draws an index from `u` in [0,1); also returns where `u` fell inside
    /// its interval, rescaled to [0,1) (for reuse as a fresh random number).
    pub fn sample(&self, u: f32) -> (usize, f32) {
        // The last index whose cdf is <= u, skipping zero-width entries.
        let i = self.cdf.partition_point(|&c| c <= u).clamp(1, self.len()) - 1;
        let width = self.cdf[i + 1] - self.cdf[i];
        let rest = if width > 0.0 {
            ((u - self.cdf[i]) / width).clamp(0.0, 0.999_999_94)
        } else {
            0.5
        };
        (i, rest)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pcg_streams_are_deterministic_and_distinct() {
        let a: Vec<u32> = (0..4)
            .map({
                let mut r = Pcg32::new(7, 3);
                move |_| r.next_u32()
            })
            .collect();
        let b: Vec<u32> = (0..4)
            .map({
                let mut r = Pcg32::new(7, 3);
                move |_| r.next_u32()
            })
            .collect();
        let c: Vec<u32> = (0..4)
            .map({
                let mut r = Pcg32::new(7, 4);
                move |_| r.next_u32()
            })
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        let mut r = Pcg32::new(1, 1);
        let mean = (0..100_000).map(|_| r.next_f32() as f64).sum::<f64>() / 100_000.0;
        assert!((mean - 0.5).abs() < 0.01, "{mean}");
    }

    #[test]
    fn cosine_samples_have_the_right_mean_height() {
        // E[cos theta] under the cosine density is 2/3.
        let mut r = Pcg32::new(3, 0);
        let n = 200_000;
        let mean: f64 = (0..n)
            .map(|_| cosine_hemisphere(r.next_2d()).z as f64)
            .sum::<f64>()
            / n as f64;
        assert!((mean - 2.0 / 3.0).abs() < 0.005, "{mean}");
    }

    #[test]
    fn distributions_follow_their_weights() {
        let d = Distribution1d::new(&[1.0, 0.0, 3.0]);
        assert_eq!(d.probability(1), 0.0);
        assert!((d.probability(2) - 0.75).abs() < 1e-6);
        assert_eq!(d.sample(0.1).0, 0);
        assert_eq!(d.sample(0.25).0, 2, "the empty entry is never drawn");
        assert_eq!(d.sample(0.999).0, 2);
        let (_, rest) = d.sample(0.625);
        assert!((rest - 0.5).abs() < 1e-6);
        let uniform = Distribution1d::new(&[0.0, 0.0]);
        assert_eq!(uniform.probability(0), 0.5);
    }

    #[test]
    fn strata_cover_the_pixel() {
        let mut cells = [false; 16];
        for i in 0..16 {
            let [x, y] = stratified_2d(i, 16, [0.5, 0.5]);
            cells[(y * 4.0) as usize * 4 + (x * 4.0) as usize] = true;
        }
        assert!(cells.iter().all(|&c| c));
    }
}
