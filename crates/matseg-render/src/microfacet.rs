//! The GGX (Trowbridge-Reitz) microfacet distribution with Smith masking,
//! sampling of visible normals, and Fresnel terms. Directions are in the
//! local shading frame (normal = +z).

use crate::math::Vec3;
use crate::sampling::concentric_disk;
use std::f32::consts::PI;

/// Smallest GGX alpha: smoother surfaces are treated as this smooth, which
/// keeps every lobe finite (no delta distributions anywhere).
pub const MIN_ALPHA: f32 = 0.01;

/// An isotropic GGX distribution of microfacet normals.
#[derive(Clone, Copy, Debug)]
pub struct Ggx {
    /// Width; `roughness^2` in the usual artist parameterisation.
    pub alpha: f32,
}

impl Ggx {
    /// From perceptual roughness in [0, 1].
    pub fn from_roughness(roughness: f32) -> Self {
        let r = roughness.clamp(0.0, 1.0);
        Ggx {
            alpha: (r * r).max(MIN_ALPHA),
        }
    }

    /// Density of microfacet normals `wm` (per unit projected area).
    #[inline]
    pub fn d(&self, wm: Vec3) -> f32 {
        let cos2 = wm.z * wm.z;
        if cos2 <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let tan2 = (1.0 - cos2) / cos2;
        let e = 1.0 + tan2 / a2;
        1.0 / (PI * a2 * cos2 * cos2 * e * e)
    }

    /// Smith's Lambda.
    #[inline]
    fn lambda(&self, w: Vec3) -> f32 {
        let cos2 = w.z * w.z;
        if cos2 <= 0.0 {
            return f32::INFINITY;
        }
        let tan2 = (1.0 - cos2) / cos2;
        ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0) * 0.5
    }

    /// Masking of one direction.
    #[inline]
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing of a pair.
    #[inline]
    pub fn g(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of visible normals `wm` seen from `w` (per solid angle of wm).
    #[inline]
    pub fn visible_pdf(&self, w: Vec3, wm: Vec3) -> f32 {
        if w.z == 0.0 {
            return 0.0;
        }
        self.g1(w) / w.z.abs() * self.d(wm) * w.dot(wm).abs()
    }

    /// Draws a visible normal seen from `w` (Heitz 2018, the spherical-cap
    /// free version of the stretched disk construction).
    pub fn sample_visible(&self, w: Vec3, u: [f32; 2]) -> Vec3 {
        let mut wh = Vec3::new(self.alpha * w.x, self.alpha * w.y, w.z).normalised();
        if wh.z < 0.0 {
            wh = -wh;
        }
        let t1 = if wh.z < 0.99999 {
            Vec3::Z.cross(wh).normalised()
        } else {
            Vec3::new(1.0, 0.0, 0.0)
        };
        let t2 = wh.cross(t1);
        let [px, py] = concentric_disk(u);
        let h = (1.0 - px * px).max(0.0).sqrt();
        let s = 0.5 * (1.0 + wh.z);
        let py = (1.0 - s) * h + s * py;
        let pz = (1.0 - px * px - py * py).max(0.0).sqrt();
        let nh = t1 * px + t2 * py + wh * pz;
        Vec3::new(self.alpha * nh.x, self.alpha * nh.y, nh.z.max(1e-6)).normalised()
    }
}

/// Unpolarised Fresnel reflectance of a dielectric interface for a
/// direction at `cos_i` to the normal, relative index `eta` (inside over
/// outside). Negative `cos_i` means arriving from inside.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let (cos_i, eta) = if cos_i < 0.0 {
        (-cos_i, 1.0 / eta)
    } else {
        (cos_i, eta)
    };
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (parallel * parallel + perpendicular * perpendicular)
}

/// Schlick's approximation with a coloured reflectance at normal incidence.
#[inline]
pub fn fresnel_schlick(f0: Vec3, cos_i: f32) -> Vec3 {
    let m = (1.0 - cos_i.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::ONE - f0) * m
}

/// Mirror reflection of `w` about `n`.
#[inline]
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    n * (2.0 * w.dot(n)) - w
}

/// Refraction of `wi` through an interface with normal `n` and relative
/// index `eta`; `None` on total internal reflection. Also returns the
/// relative index actually crossed (`eta` or `1/eta` from inside).
pub fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let mut cos_i = n.dot(wi);
    let (mut eta, mut n) = (eta, n);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wi / eta + n * (cos_i / eta - cos_t), eta))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{uniform_sphere, Pcg32};

    #[test]
    fn projected_normal_density_integrates_to_one() {
        // ∫ D(m) cos(m) dm = 1 over the hemisphere, by uniform sampling.
        for roughness in [0.3, 0.6, 1.0] {
            let ggx = Ggx::from_roughness(roughness);
            let mut rng = Pcg32::new(5, 0);
            let n = 400_000;
            let sum: f64 = (0..n)
                .map(|_| {
                    let m = uniform_sphere(rng.next_2d());
                    if m.z > 0.0 {
                        (ggx.d(m) * m.z) as f64 * 4.0 * std::f64::consts::PI
                    } else {
                        0.0
                    }
                })
                .sum();
            let integral = sum / n as f64;
            assert!(
                (integral - 1.0).abs() < 0.03,
                "roughness {roughness}: {integral}"
            );
        }
    }

    #[test]
    fn visible_normals_follow_their_density() {
        // The mean of z under samples equals ∫ z * visible_pdf by uniform sampling.
        let ggx = Ggx::from_roughness(0.7);
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let mut rng = Pcg32::new(9, 0);
        let n = 300_000;
        let sampled: f64 = (0..n)
            .map(|_| ggx.sample_visible(wo, rng.next_2d()).z as f64)
            .sum::<f64>()
            / n as f64;
        let integrated: f64 = (0..n)
            .map(|_| {
                let m = uniform_sphere(rng.next_2d());
                (m.z.max(0.0) * ggx.visible_pdf(wo, m) * (wo.dot(m) > 0.0) as i32 as f32) as f64
                    * 4.0
                    * std::f64::consts::PI
            })
            .sum::<f64>()
            / n as f64;
        assert!(
            (sampled - integrated).abs() < 0.01,
            "{sampled} vs {integrated}"
        );
    }

    #[test]
    fn fresnel_matches_known_values() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert_eq!(
            fresnel_dielectric(-0.3, 1.5),
            1.0,
            "total internal reflection"
        );
        assert!((fresnel_dielectric(1e-4, 1.5) - 1.0).abs() < 1e-2);
        let (t, eta) = refract(Vec3::Z, Vec3::Z, 1.5).unwrap();
        assert!((t + Vec3::Z).length() < 1e-6 && eta == 1.5);
        // Snell: sin 30° outside -> sin = 1/3 inside.
        let wi = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
        let (t, _) = refract(wi, Vec3::Z, 1.5).unwrap();
        assert!((t.x + 0.5 / 1.5).abs() < 1e-6 && t.z < 0.0);
    }
}
