//! The colour part of a descriptor: each stride-4 cell's mean CIE L*a*b*
//! colour as random Fourier features, so that the cosine of two cells'
//! parts approximates a Gaussian kernel of their colour distance,
//! exp(-|lab1 - lab2|^2 / (2 bandwidth^2)) (Rahimi and Recht, 2007). The
//! projection and phases are fixed (drawn once from a fixed seed and stored
//! with the weights); the part's weight and the kernel's bandwidth are
//! learned. Colour is what the `lab` baseline scores with, and a net's
//! stride-4 features, smoothed by its decoder, lose some of it.

use crate::net::denormalise_input;
use matseg_image::lab::{D65_WHITE_XZ, LAB_EPSILON, LAB_KAPPA, LINEAR_SRGB_TO_XYZ};
pub use matseg_model::config::COLOUR_FEATURES;
use tch::{nn, Tensor};

/// The kernel's bandwidth before training, in L*a*b* units.
pub const INITIAL_BANDWIDTH: f64 = 15.0;

/// The prefix of the colour part's variable names in a net.
pub const COLOUR_PART: &str = "colour.";

/// Seed of the fixed projection and phases.
pub const SEED: u64 = 0xc010_0e5e;

/// The colour part's variables (under the net's `colour` path).
#[derive(Debug)]
pub struct ColourPart {
    /// `[COLOUR_FEATURES, 3]` standard normal directions (not trained).
    projection: Tensor,
    /// `[COLOUR_FEATURES]` phases in [0, 2 pi) (not trained).
    phase: Tensor,
    /// Log of the part's weight in the descriptor (0 at first: the weight
    /// of the other parts).
    log_weight: Tensor,
    /// Log of the kernel's bandwidth in L*a*b* units.
    log_bandwidth: Tensor,
}

impl ColourPart {
    /// Creates the variables under `p`: the fixed projection and phases
    /// drawn from [`SEED`], weight 1 and bandwidth [`INITIAL_BANDWIDTH`].
    pub fn new(p: &nn::Path) -> Self {
        let mut draws = SplitMix64(SEED);
        let normals: Vec<f32> = (0..COLOUR_FEATURES * 3)
            .map(|_| draws.standard_normal() as f32)
            .collect();
        let phases: Vec<f32> = (0..COLOUR_FEATURES)
            .map(|_| (draws.uniform() * std::f64::consts::TAU) as f32)
            .collect();
        let mut projection = p.zeros_no_train("projection", &[COLOUR_FEATURES, 3]);
        let mut phase = p.zeros_no_train("phase", &[COLOUR_FEATURES]);
        tch::no_grad(|| {
            projection.copy_(&Tensor::from_slice(&normals).view([COLOUR_FEATURES, 3]));
            phase.copy_(&Tensor::from_slice(&phases));
        });
        let log_weight = p.zeros("log_weight", &[1]);
        let log_bandwidth = p.var(
            "log_bandwidth",
            &[1],
            nn::Init::Const(INITIAL_BANDWIDTH.ln()),
        );
        Self {
            projection,
            phase,
            log_weight,
            log_bandwidth,
        }
    }

    /// The weighted part `[N, COLOUR_FEATURES, h4, w4]` (each cell's
    /// features of unit length times the part's weight) of the net's input
    /// `x` `[N, 3, H, W]`, prepared by [`crate::normalise_input`]: its
    /// colours averaged over each cell of an `h4` x `w4` grid.
    pub fn forward(&self, x: &Tensor, h4: i64, w4: i64) -> Tensor {
        self.forward_cells(&cell_lab(x, h4, w4))
    }

    /// The weighted part of cells whose mean L*a*b* colours
    /// `[N, 3, h, w]` ([`cell_lab`]) are given.
    pub fn forward_cells(&self, lab: &Tensor) -> Tensor {
        let scaled = lab / self.log_bandwidth.exp();
        // [N, 3, h, w] -> [N, h, w, 3] x [3, M] -> [N, M, h, w]
        let angles = scaled
            .permute([0, 2, 3, 1])
            .matmul(&self.projection.tr())
            .permute([0, 3, 1, 2])
            + self.phase.view([1, COLOUR_FEATURES, 1, 1]);
        crate::blocks::l2_normalise(&angles.cos(), 1) * self.log_weight.exp()
    }
}

/// The mean CIE L*a*b* colour `[N, 3, h4, w4]` of each cell of an `h4` x
/// `w4` grid over the net's input `x` `[N, 3, H, W]` (prepared by
/// [`crate::normalise_input`]): what the colour part reads of an image.
pub fn cell_lab(x: &Tensor, h4: i64, w4: i64) -> Tensor {
    let rgb = denormalise_input(x).clamp(0.0, 255.0);
    srgb_to_lab(&rgb).adaptive_avg_pool2d([h4, w4])
}

/// CIE L*a*b* (D65 white) `[N, 3, H, W]` of sRGB levels 0..255 `[N, 3, H,
/// W]`: the conversion of the `lab` baseline, on tensors.
pub fn srgb_to_lab(rgb: &Tensor) -> Tensor {
    let c = rgb / 255.0;
    // (`a.where_self(condition, b)` is a where the condition holds, else b.)
    let linear = (&c / 12.92).where_self(
        &c.le(0.04045),
        &((&c + 0.055) / 1.055).pow_tensor_scalar(2.4),
    );
    // Rows divided by the white point, so that X and Z come out normalised.
    let [mx, my, mz] = LINEAR_SRGB_TO_XYZ;
    let [wx, wz] = D65_WHITE_XZ;
    let normalised: Vec<f32> = [mx.map(|m| m / wx), my, mz.map(|m| m / wz)].concat();
    let matrix = Tensor::from_slice(&normalised)
        .view([3, 3])
        .to_kind(rgb.kind())
        .to_device(rgb.device());
    let xyz = linear
        .permute([0, 2, 3, 1])
        .matmul(&matrix.tr())
        .permute([0, 3, 1, 2]);
    let epsilon = f64::from(LAB_EPSILON);
    let f = xyz
        .clamp_min(epsilon)
        .pow_tensor_scalar(1.0 / 3.0)
        .where_self(
            &xyz.gt(epsilon),
            &((&xyz * f64::from(LAB_KAPPA) + 16.0) / 116.0),
        );
    let (fx, fy, fz) = (f.select(1, 0), f.select(1, 1), f.select(1, 2));
    Tensor::stack(
        &[&fy * 116.0 - 16.0, (&fx - &fy) * 500.0, (&fy - &fz) * 200.0],
        1,
    )
}

/// The SplitMix64 generator (Steele, Lea and Flood, 2014): a fixed stream
/// for the fixed projection, the same on every platform.
struct SplitMix64(u64);

impl SplitMix64 {
    /// The next 64 random bits.
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1).
    fn uniform(&mut self) -> f64 {
        ((self.next() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Standard normal (Box-Muller).
    fn standard_normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use matseg_image::lab::srgb_to_lab as reference_lab;
    use tch::{Device, Kind};

    /// An `[1, 3, 1, n]` tensor of 0..255 colours.
    fn colours(rgb: &[[u8; 3]]) -> Tensor {
        let values: Vec<f32> = rgb.iter().flat_map(|c| c.map(f32::from)).collect();
        Tensor::from_slice(&values)
            .view([1, rgb.len() as i64, 3])
            .permute([0, 2, 1])
            .unsqueeze(2)
    }

    #[test]
    fn lab_on_tensors_matches_the_lab_baseline() {
        let rgb = [
            [0, 0, 0],
            [255, 255, 255],
            [255, 0, 0],
            [12, 200, 90],
            [3, 4, 5],
            [128, 64, 250],
        ];
        let lab = srgb_to_lab(&colours(&rgb));
        for (i, c) in rgb.iter().enumerate() {
            let expected = reference_lab(*c);
            for (channel, want) in expected.iter().enumerate() {
                let got = lab.double_value(&[0, channel as i64, 0, i as i64]) as f32;
                assert!(
                    (got - want).abs() < 1e-3,
                    "{c:?} channel {channel}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn the_colour_part_is_a_gaussian_kernel_of_lab_distance() {
        let vs = nn::VarStore::new(Device::Cpu);
        let part = ColourPart::new(&vs.root());
        // The projection is fixed by the seed: standard normal draws.
        let draws = part.projection.flatten(0, -1);
        assert!(draws.mean(Kind::Float).double_value(&[]).abs() < 0.1);
        assert!((draws.std(true).double_value(&[]) - 1.0).abs() < 0.1);
        assert_eq!(
            part.projection,
            ColourPart::new(&nn::VarStore::new(Device::Cpu).root()).projection
        );
        // Pairs of colours and their Lab distances.
        let pairs = [
            ([120, 80, 60], [120, 80, 60]),
            ([120, 80, 60], [125, 84, 62]),
            ([120, 80, 60], [140, 90, 70]),
            ([120, 80, 60], [60, 120, 200]),
            ([0, 0, 0], [255, 255, 255]),
        ];
        let first: Vec<[u8; 3]> = pairs.iter().map(|p| p.0).collect();
        let second: Vec<[u8; 3]> = pairs.iter().map(|p| p.1).collect();
        let n = pairs.len() as i64;
        let input = |rgb: &[[u8; 3]]| crate::normalise_input(&colours(rgb));
        let a = tch::no_grad(|| part.forward(&input(&first), 1, n));
        let b = tch::no_grad(|| part.forward(&input(&second), 1, n));
        for (i, (x, y)) in pairs.iter().enumerate() {
            let cosine = (a.select(3, i as i64) * b.select(3, i as i64))
                .sum(Kind::Float)
                .double_value(&[]);
            let d2: f32 = reference_lab(*x)
                .iter()
                .zip(reference_lab(*y))
                .map(|(p, q)| (p - q) * (p - q))
                .sum();
            let kernel = (-(d2 as f64) / (2.0 * INITIAL_BANDWIDTH * INITIAL_BANDWIDTH)).exp();
            // 128 features: the estimate's error is about 0.06 at most.
            assert!(
                (cosine - kernel).abs() < 0.2,
                "{x:?} {y:?}: {cosine} vs {kernel}"
            );
            if x == y {
                assert!((cosine - 1.0).abs() < 1e-5);
            }
        }
    }
}
