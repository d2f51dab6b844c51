//! Automatic segmentation: spherical k-means on a descriptor map, for when
//! the user gives no points (`matseg segment --auto K`).
//!
//! Centres are fitted on an even subsample of the pixels (k-means++ seeding
//! from a fixed seed, then Lloyd iterations on unit vectors: each centre is
//! the normalised sum of its members), and every pixel then takes the label
//! of the centre with the highest cosine similarity. The same map, `k` and
//! seed always give the same labels.

use crate::descriptor::DescriptorMap;
use rand::{Rng, SeedableRng};

/// Settings of [`cluster_descriptors`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClusterOptions {
    /// Number of clusters.
    pub k: usize,
    /// At most this many pixels (an even grid of them) fit the centres.
    pub max_samples: usize,
    /// At most this many Lloyd iterations (fewer if the labels settle).
    pub max_iterations: usize,
    /// Seed of the k-means++ seeding.
    pub seed: u64,
}

impl ClusterOptions {
    /// `k` clusters from 20,000 pixels, 50 iterations, seed 0.
    pub fn new(k: usize) -> Self {
        Self {
            k,
            max_samples: 20_000,
            max_iterations: 50,
            seed: 0,
        }
    }
}

/// A clustering: one label per pixel and the unit centres.
#[derive(Clone, Debug, PartialEq)]
pub struct Clustering {
    /// Row-major label of every pixel, in `0..k`.
    pub labels: Vec<u32>,
    /// `k` unit centres of `dim` values each.
    pub centres: Vec<Vec<f32>>,
}

/// Clusters the pixels of `map` by cosine similarity of their descriptors.
/// `k` is clamped to the number of sampled pixels (and at least 1).
pub fn cluster_descriptors(map: &DescriptorMap, options: &ClusterOptions) -> Clustering {
    let pixels = map.width * map.height;
    let unit = |i: usize| -> Vec<f32> { normalised(map.at(i)) };
    let stride = pixels.div_ceil(options.max_samples.max(1)).max(1);
    let samples: Vec<Vec<f32>> = (0..pixels).step_by(stride).map(unit).collect();
    let k = options.k.clamp(1, samples.len().max(1));
    let mut centres = seed_centres(&samples, k, options.seed);
    let mut assigned = vec![usize::MAX; samples.len()];
    for _ in 0..options.max_iterations {
        let mut changed = false;
        for (a, s) in assigned.iter_mut().zip(&samples) {
            let best = nearest(&centres, s);
            changed |= *a != best;
            *a = best;
        }
        if !changed {
            break;
        }
        let mut sums = vec![vec![0f64; map.dim]; k];
        for (&a, s) in assigned.iter().zip(&samples) {
            for (t, &v) in sums[a].iter_mut().zip(s) {
                *t += v as f64;
            }
        }
        for (c, sum) in centres.iter_mut().zip(&sums) {
            // An emptied cluster keeps its centre.
            if sum.iter().any(|&v| v != 0.0) {
                *c = normalised(&sum.iter().map(|&v| v as f32).collect::<Vec<_>>());
            }
        }
    }
    let labels = (0..pixels)
        .map(|i| nearest(&centres, map.at(i)) as u32)
        .collect();
    Clustering { labels, centres }
}

/// k-means++ seeding on cosine distance (1 - cos): the first centre at
/// random, each next one drawn with probability proportional to the squared
/// distance to the nearest centre so far.
fn seed_centres(samples: &[Vec<f32>], k: usize, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut centres = vec![samples[rng.random_range(0..samples.len())].clone()];
    let mut distance: Vec<f64> = samples
        .iter()
        .map(|s| cosine_distance(&centres[0], s))
        .collect();
    while centres.len() < k {
        let weights: Vec<f64> = distance.iter().map(|d| d * d).collect();
        let total: f64 = weights.iter().sum();
        let pick = if total > 0.0 {
            let mut r = rng.random::<f64>() * total;
            weights
                .iter()
                .position(|&w| {
                    r -= w;
                    r < 0.0
                })
                .unwrap_or(samples.len() - 1)
        } else {
            // Every sample sits on a centre: any one will do.
            rng.random_range(0..samples.len())
        };
        let centre = samples[pick].clone();
        for (d, s) in distance.iter_mut().zip(samples) {
            *d = d.min(cosine_distance(&centre, s));
        }
        centres.push(centre);
    }
    centres
}

/// Index of the centre with the highest dot product with `v` (the first on
/// ties).
fn nearest(centres: &[Vec<f32>], v: &[f32]) -> usize {
    let mut best = (0, f32::NEG_INFINITY);
    for (j, c) in centres.iter().enumerate() {
        let dot: f32 = c.iter().zip(v).map(|(a, b)| a * b).sum();
        if dot > best.1 {
            best = (j, dot);
        }
    }
    best.0
}

fn cosine_distance(a: &[f32], b: &[f32]) -> f64 {
    let dot: f32 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    (1.0 - dot as f64).max(0.0)
}

fn normalised(v: &[f32]) -> Vec<f32> {
    let n = v.iter().map(|x| x * x).sum::<f32>().sqrt().max(1e-12);
    v.iter().map(|x| x / n).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 30x20 map whose pixels point near one of three directions: left
    /// third along x, middle along y, right along z, with noise.
    fn three_regions(noise: f32) -> (DescriptorMap, Vec<u32>) {
        let (w, h) = (30, 20);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut data = Vec::new();
        let mut truth = Vec::new();
        for _ in 0..h {
            for x in 0..w {
                let region = x / 10;
                let mut d = [0f32; 3];
                d[region] = 2.0;
                for v in &mut d {
                    *v += noise * (rng.random::<f32>() - 0.5);
                }
                data.extend(d);
                truth.push(region as u32);
            }
        }
        let map = DescriptorMap {
            width: w,
            height: h,
            dim: 3,
            data,
        };
        (map, truth)
    }

    #[test]
    fn recovers_separated_regions_up_to_renaming() {
        let (map, truth) = three_regions(0.8);
        let c = cluster_descriptors(&map, &ClusterOptions::new(3));
        let mut rename = [u32::MAX; 3];
        for (&t, &l) in truth.iter().zip(&c.labels) {
            if rename[t as usize] == u32::MAX {
                rename[t as usize] = l;
            }
            assert_eq!(rename[t as usize], l, "region {t} split");
        }
        let mut used = rename.to_vec();
        used.sort();
        assert_eq!(used, vec![0, 1, 2]);
        for centre in &c.centres {
            let n: f32 = centre.iter().map(|v| v * v).sum();
            assert!((n - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn same_seed_same_labels_and_subsampling_agrees() {
        let (map, _) = three_regions(0.8);
        let all = cluster_descriptors(&map, &ClusterOptions::new(3));
        assert_eq!(all, cluster_descriptors(&map, &ClusterOptions::new(3)));
        let few = ClusterOptions {
            max_samples: 50,
            ..ClusterOptions::new(3)
        };
        let sub = cluster_descriptors(&map, &few);
        // The same partition, whatever the label names.
        for i in 0..all.labels.len() {
            for j in [0, 15, 29] {
                assert_eq!(
                    all.labels[i] == all.labels[j],
                    sub.labels[i] == sub.labels[j]
                );
            }
        }
    }

    #[test]
    fn k_is_clamped_to_the_pixels() {
        let map = DescriptorMap {
            width: 2,
            height: 1,
            dim: 2,
            data: vec![1.0, 0.0, 0.0, 1.0],
        };
        let c = cluster_descriptors(&map, &ClusterOptions::new(5));
        assert_eq!(c.centres.len(), 2);
        assert_ne!(c.labels[0], c.labels[1]);
        let one = cluster_descriptors(&map, &ClusterOptions::new(0));
        assert_eq!(one.labels, vec![0, 0]);
    }
}
