//! Light from far away: an equirectangular HDRI (turned about the vertical
//! axis and scaled), importance-sampled by its luminance, plus point and
//! spot lights.

use crate::hdr_io::HdrImage;
use crate::math::Vec3;
use crate::sampling::AliasTable;
use serde::{Deserialize, Serialize};
use std::f32::consts::PI;
use std::sync::Arc;

/// What a draw from one bin of the alias table needs besides the table:
/// for the bin's own pixel and its alias pixel, their probabilities and
/// radiance, side by side so a draw touches few places in memory.
#[derive(Clone, Copy, Debug)]
struct SamplingBin {
    alias: u32,
    probability: [f32; 2],
    radiance: [Vec3; 2],
}

/// An HDRI with its importance-sampling table (pixels by luminance times
/// their solid angle, as an alias table): built once per file, shared
/// between scenes.
#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    image: HdrImage,
    /// Probability of each pixel.
    probability: Vec<f32>,
    table: AliasTable,
    bins: Vec<SamplingBin>,
}

impl EnvironmentMap {
    /// Builds the sampling table of `image`.
    pub fn new(image: HdrImage) -> Self {
        let (w, h) = (image.width, image.height);
        let weights: Vec<f32> = (0..w * h)
            .map(|i| {
                let sin = (PI * ((i / w) as f32 + 0.5) / h as f32).sin();
                image.pixels[i].luminance().max(0.0) * sin
            })
            .collect();
        let table = AliasTable::new(&weights);
        let probability: Vec<f32> = (0..w * h).map(|i| table.probability(i)).collect();
        let bins = table
            .bins()
            .iter()
            .enumerate()
            .map(|(i, &(_, alias))| SamplingBin {
                alias,
                probability: [probability[i], probability[alias as usize]],
                radiance: [image.pixels[i], image.pixels[alias as usize]],
            })
            .collect();
        EnvironmentMap {
            probability,
            bins,
            table,
            image,
        }
    }

    /// Bytes held (for cache bounds).
    pub fn bytes(&self) -> usize {
        self.image.pixels.len()
            * (std::mem::size_of::<Vec3>() + 4 + std::mem::size_of::<SamplingBin>())
    }
}

/// An environment map in a scene: shared tables, plus this scene's strength
/// and rotation. As in Blender: a direction (x, y, z), z up, first turned
/// about z by the rotation, maps to image column `-atan2(y, x) / 2pi`
/// (mod 1) and its zenith angle to the row, the zenith on top, so a scene
/// looks the same rendered here or by Cycles.
#[derive(Clone, Debug)]
pub struct Environment {
    map: Arc<EnvironmentMap>,
    strength: f32,
    rotation: f32,
}

impl Environment {
    /// From an HDRI, a multiplier and a rotation in degrees.
    pub fn new(image: HdrImage, strength: f32, rotation_deg: f32) -> Self {
        Environment::with_map(Arc::new(EnvironmentMap::new(image)), strength, rotation_deg)
    }

    /// From shared tables, a multiplier and a rotation in degrees.
    pub fn with_map(map: Arc<EnvironmentMap>, strength: f32, rotation_deg: f32) -> Self {
        Environment {
            map,
            strength,
            rotation: rotation_deg.to_radians(),
        }
    }

    /// The same radiance from every direction. (A 32x16 map rather than
    /// one pixel, so that importance sampling by rows is close to uniform
    /// over the sphere.)
    pub fn uniform(radiance: Vec3) -> Self {
        Environment::new(
            HdrImage {
                width: 32,
                height: 16,
                pixels: vec![radiance; 32 * 16],
            },
            1.0,
            0.0,
        )
    }

    /// Image coordinates in [0,1)² of a unit direction.
    #[inline]
    fn uv(&self, d: Vec3) -> (f32, f32) {
        // Blender's equirectangular convention: longitude increases to the
        // left of the image; the rotation turns the direction first.
        let phi = d.y.atan2(d.x) + self.rotation;
        let u = (-phi / (2.0 * PI)).rem_euclid(1.0);
        let v = d.z.clamp(-1.0, 1.0).acos() / PI;
        (u, v)
    }

    /// The pixel holding image coordinates (u, v).
    #[inline]
    fn pixel(&self, u: f32, v: f32) -> (usize, usize) {
        let (w, h) = (self.map.image.width, self.map.image.height);
        (
            ((u * w as f32) as usize).min(w - 1),
            ((v * h as f32) as usize).min(h - 1),
        )
    }

    /// Radiance arriving from unit direction `d` (bilinear between pixels).
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        let (u, v) = self.uv(d);
        let (w, h) = (self.map.image.width, self.map.image.height);
        let x = u * w as f32 - 0.5;
        let y = (v * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = (x - x0, y - y0);
        let xi = |x: f32| (x as i64).rem_euclid(w as i64) as usize;
        let (xa, xb) = (xi(x0), xi(x0 + 1.0));
        let (ya, yb) = (y0 as usize, (y0 as usize + 1).min(h - 1));
        let p = |x: usize, y: usize| self.map.image.pixels[y * w + x];
        let top = p(xa, ya).lerp(p(xb, ya), tx);
        let bottom = p(xa, yb).lerp(p(xb, yb), tx);
        top.lerp(bottom, ty) * self.strength
    }

    /// The pixel unit direction `d` falls in, and the density
    /// [`Environment::sample`] gives `d`.
    #[inline]
    fn lookup(&self, d: Vec3) -> (usize, f32) {
        let (u, v) = self.uv(d);
        let (x, y) = self.pixel(u, v);
        let (w, h) = (self.map.image.width, self.map.image.height);
        let i = y * w + x;
        let st = (1.0 - d.z * d.z).max(0.0).sqrt();
        if self.map.table.total() <= 0.0 || st <= 0.0 {
            return (i, 0.0);
        }
        (
            i,
            self.map.probability[i] * (w * h) as f32 / (2.0 * PI * PI * st),
        )
    }

    /// Radiance from unit direction `d`, constant over each pixel (the
    /// function light sampling draws from; the paths it is weighed against
    /// use this one), and the density [`Environment::sample`] gives `d`:
    /// one lookup for both.
    pub fn radiance_and_pdf(&self, d: Vec3) -> (Vec3, f32) {
        let (i, pdf) = self.lookup(d);
        (self.map.image.pixels[i] * self.strength, pdf)
    }

    /// Draws a direction proportionally to luminance: the direction, its
    /// radiance (as [`Environment::radiance_and_pdf`]) and its solid-angle
    /// density.
    pub fn sample(&self, u: [f32; 2]) -> Option<(Vec3, Vec3, f32)> {
        let map = &self.map;
        if map.table.total() <= 0.0 {
            return None;
        }
        let (bin, alias, fx) = map.table.draw(u[0]);
        let b = &map.bins[bin];
        let (k, i) = if alias {
            (1, b.alias as usize)
        } else {
            (0, bin)
        };
        let (w, h) = (map.image.width, map.image.height);
        let (px, py) = (i % w, i / w);
        let (uu, vv) = ((px as f32 + fx) / w as f32, (py as f32 + u[1]) / h as f32);
        let theta = PI * vv;
        let phi = -2.0 * PI * uu - self.rotation;
        let (st, ct) = theta.sin_cos();
        if st <= 0.0 {
            return None;
        }
        let d = Vec3::new(st * phi.cos(), st * phi.sin(), ct);
        let pdf = b.probability[k] * (w * h) as f32 / (2.0 * PI * PI * st);
        Some((d, b.radiance[k] * self.strength, pdf))
    }

    /// The density [`Environment::sample`] gives unit direction `d`.
    pub fn pdf(&self, d: Vec3) -> f32 {
        self.lookup(d).1
    }

    /// Largest and mean radiance over the sphere (solid-angle weighted).
    pub fn radiance_stats(&self) -> (f32, f32) {
        let (max, mean) = self.map.image.luminance_stats();
        (max * self.strength, mean * self.strength)
    }
}

/// A light at a point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Light {
    /// Shines equally in every direction.
    Point {
        /// Where.
        position: Vec3,
        /// Radiant intensity (W/sr) per RGB channel.
        intensity: Vec3,
    },
    /// Shines into a cone, with a smooth edge.
    Spot {
        /// Where.
        position: Vec3,
        /// The point it aims at.
        target: Vec3,
        /// Radiant intensity on the axis (W/sr).
        intensity: Vec3,
        /// Full cone angle in degrees.
        angle_deg: f32,
        /// Fraction of the cone's half-angle over which it fades (0..1).
        #[serde(default)]
        blend: f32,
    },
}

impl Light {
    /// Light arriving at `p` from this light: unit direction toward the
    /// light, its distance, and the irradiance-producing radiance term
    /// (intensity / distance², times the spot falloff).
    pub fn illuminate(&self, p: Vec3) -> Option<(Vec3, f32, Vec3)> {
        let (position, intensity) = match self {
            Light::Point {
                position,
                intensity,
            }
            | Light::Spot {
                position,
                intensity,
                ..
            } => (*position, *intensity),
        };
        let to = position - p;
        let dist2 = to.dot(to);
        if dist2 <= 0.0 {
            return None;
        }
        let dist = dist2.sqrt();
        let wi = to / dist;
        let mut value = intensity / dist2;
        if let Light::Spot {
            target,
            angle_deg,
            blend,
            ..
        } = self
        {
            let axis = (*target - position).normalised();
            let cos = (-wi).dot(axis);
            let half = (angle_deg * 0.5).to_radians();
            let outer = half.cos();
            let inner = (half * (1.0 - blend.clamp(0.0, 1.0))).cos();
            let falloff = if cos >= inner {
                1.0
            } else if cos <= outer {
                0.0
            } else {
                let t = (cos - outer) / (inner - outer);
                t * t * (3.0 - 2.0 * t)
            };
            value *= falloff;
        }
        (value.max_elem() > 0.0).then_some((wi, dist, value))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{uniform_sphere, Pcg32};

    fn sky() -> Environment {
        // A dim sky with one bright patch, 64x32.
        let (w, h) = (64, 32);
        let pixels = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (10..13).contains(&x) && (6..9).contains(&y) {
                    Vec3::new(500.0, 400.0, 300.0)
                } else {
                    Vec3::splat(0.5 + y as f32 / 64.0)
                }
            })
            .collect();
        Environment::new(
            HdrImage {
                width: w,
                height: h,
                pixels,
            },
            1.5,
            30.0,
        )
    }

    #[test]
    fn sampling_density_integrates_to_one_and_matches_pdf() {
        let env = sky();
        let mut rng = Pcg32::new(4, 0);
        let n = 400_000;
        let total: f64 = (0..n)
            .map(|_| env.pdf(uniform_sphere(rng.next_2d())) as f64)
            .sum::<f64>()
            / n as f64
            * 4.0
            * std::f64::consts::PI;
        assert!((total - 1.0).abs() < 0.02, "{total}");
        for _ in 0..1000 {
            let (d, _, pdf) = env.sample(rng.next_2d()).unwrap();
            assert!(
                (env.pdf(d) - pdf).abs() <= 1e-3 * pdf,
                "{} vs {pdf}",
                env.pdf(d)
            );
        }
    }

    #[test]
    fn importance_sampling_estimates_the_mean_radiance() {
        // E[L / pdf] over samples = ∫ L dω, which the solid-angle mean gives too.
        let env = sky();
        let mut rng = Pcg32::new(6, 0);
        let n = 100_000;
        let est: f64 = (0..n)
            .filter_map(|_| env.sample(rng.next_2d()))
            .map(|(_, l, pdf)| (l.luminance() / pdf) as f64)
            .sum::<f64>()
            / n as f64;
        let (_, mean) = env.radiance_stats();
        let exact = mean as f64 * 4.0 * std::f64::consts::PI;
        // Bilinear lookups smooth the patch's edge a little.
        assert!((est - exact).abs() < 0.05 * exact, "{est} vs {exact}");
    }

    #[test]
    fn rotation_turns_the_map_about_the_vertical() {
        let env = sky();
        let turned = Environment::with_map(env.map.clone(), 1.5, 120.0);
        let d = Vec3::new(0.3, 0.5, 0.2).normalised();
        let (s, c) = (-90f32).to_radians().sin_cos();
        let d_turned = Vec3::new(c * d.x - s * d.y, s * d.x + c * d.y, d.z);
        assert!((env.radiance(d) - turned.radiance(d_turned)).length() < 1e-3);
    }

    #[test]
    fn spot_lights_fade_outside_their_cone() {
        let spot = Light::Spot {
            position: Vec3::new(0.0, 0.0, 10.0),
            target: Vec3::ZERO,
            intensity: Vec3::splat(100.0),
            angle_deg: 60.0,
            blend: 0.2,
        };
        let (wi, dist, value) = spot.illuminate(Vec3::ZERO).unwrap();
        assert_eq!((wi, dist, value), (Vec3::Z, 10.0, Vec3::splat(1.0)));
        assert!(
            spot.illuminate(Vec3::new(10.0, 0.0, 0.0)).is_none(),
            "45° is outside a 60° cone"
        );
        let (_, _, edge) = spot.illuminate(Vec3::new(5.5, 0.0, 0.0)).unwrap();
        assert!(
            edge.x > 0.0 && edge.x < 100.0 / (100.0 + 5.5 * 5.5),
            "fading at 28.8°"
        );
    }
}
