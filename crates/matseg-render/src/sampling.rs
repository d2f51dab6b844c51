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

/// Walker's alias table (built by Vose's method): draws an index with
/// probability proportional to given weights in constant time, one lookup,
/// and tells that probability back.
#[derive(Clone, Debug)]
pub struct AliasTable {
    /// Per bin: the probability of keeping the bin's own index, and the
    /// other index it sends the rest to.
    bins: Vec<(f32, u32)>,
    /// Normalised probability of each index.
    pmf: Vec<f32>,
    /// The weights' sum before normalising.
    total: f64,
}

impl AliasTable {
    /// From non-negative weights; all-zero weights become uniform.
    pub fn new(weights: &[f32]) -> Self {
        let n = weights.len();
        let total: f64 = weights.iter().map(|&w| w.max(0.0) as f64).sum();
        let pmf: Vec<f64> = weights
            .iter()
            .map(|&w| {
                if total > 0.0 {
                    w.max(0.0) as f64 / total
                } else {
                    1.0 / n as f64
                }
            })
            .collect();
        let mut scaled: Vec<f64> = pmf.iter().map(|p| p * n as f64).collect();
        let mut bins = vec![(1.0f32, 0u32); n];
        let (mut small, mut large): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| scaled[i] < 1.0);
        while let (Some(s), Some(&l)) = (small.pop(), large.last()) {
            bins[s] = (scaled[s] as f32, l as u32);
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // What is left is 1 up to rounding: keep itself.
        for i in small.into_iter().chain(large) {
            bins[i] = (1.0, i as u32);
        }
        AliasTable {
            bins,
            pmf: pmf.iter().map(|&p| p as f32).collect(),
            total,
        }
    }

    /// The sum of the weights.
    pub fn total(&self) -> f64 {
        self.total
    }

    /// Per bin: the probability of keeping the bin's own index and the
    /// index it gives the rest to.
    pub fn bins(&self) -> &[(f32, u32)] {
        &self.bins
    }

    /// Probability of index `i`.
    #[inline]
    pub fn probability(&self, i: usize) -> f32 {
        self.pmf[i]
    }

    /// Draws from `u` in [0,1): the bin, whether its alias was taken (the
    /// index drawn is then `bins()[bin].1`, else `bin`), and a fresh uniform
    /// number in [0,1) made from what `u` did not use.
    #[inline]
    pub fn draw(&self, u: f32) -> (usize, bool, f32) {
        let n = self.bins.len();
        let x = u * n as f32;
        let bin = (x as usize).min(n - 1);
        let rest = (x - bin as f32).clamp(0.0, 0.999_999_94);
        let keep = self.bins[bin].0;
        if rest < keep {
            (bin, false, (rest / keep).min(0.999_999_94))
        } else {
            (
                bin,
                true,
                ((rest - keep) / (1.0 - keep)).clamp(0.0, 0.999_999_94),
            )
        }
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
    fn alias_tables_draw_by_weight() {
        let weights = [1.0, 0.0, 3.0, 0.5, 2.5];
        let table = AliasTable::new(&weights);
        assert_eq!(table.probability(1), 0.0);
        assert!((table.probability(2) - 3.0 / 7.0).abs() < 1e-6);
        let mut counts = [0usize; 5];
        let mut rest_sum = 0.0;
        let n = 200_000;
        let mut rng = Pcg32::new(12, 0);
        for _ in 0..n {
            let (bin, alias, rest) = table.draw(rng.next_f32());
            let i = if alias {
                table.bins()[bin].1 as usize
            } else {
                bin
            };
            counts[i] += 1;
            rest_sum += rest as f64;
        }
        assert_eq!(counts[1], 0, "a zero weight is never drawn");
        for (c, w) in counts.iter().zip(weights) {
            let expected = w as f64 / 7.0;
            assert!(
                (*c as f64 / n as f64 - expected).abs() < 0.005,
                "{counts:?}"
            );
        }
        assert!(
            (rest_sum / n as f64 - 0.5).abs() < 0.005,
            "the rest is uniform"
        );
        let uniform = AliasTable::new(&[0.0, 0.0]);
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
