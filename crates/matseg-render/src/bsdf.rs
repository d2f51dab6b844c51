//! The surface scattering model: a principled-style material split into
//! three lobes, one of which is picked per shading point with the
//! material's weights (metallic, then transmission), which is an unbiased
//! estimate of their mixture:
//! - plastic: GGX reflection with dielectric Fresnel over a Lambertian base
//!   that receives what the interface lets through;
//! - metal: GGX reflection with Schlick Fresnel tinted by the base colour;
//! - glass: rough dielectric reflection and refraction (Walter et al. 2007),
//!   the transmission tinted by the base colour.
//!
//! Directions are local (shading normal = +z); `wo` points away from the
//! surface toward the viewer, `wi` toward the light.

use crate::math::Vec3;
use crate::microfacet::{fresnel_dielectric, fresnel_schlick, reflect, refract, Ggx};
use std::f32::consts::FRAC_1_PI;

/// One scattering lobe with its parameters.
#[derive(Clone, Copy, Debug)]
pub enum Lobe {
    /// Dielectric coating over a diffuse base.
    Plastic {
        /// Diffuse albedo (linear RGB).
        base: Vec3,
        /// Roughness of the coating.
        ggx: Ggx,
        /// Index of refraction of the coating.
        eta: f32,
    },
    /// A conductor.
    Metal {
        /// Reflectance at normal incidence (linear RGB).
        f0: Vec3,
        /// Roughness.
        ggx: Ggx,
    },
    /// A transparent dielectric.
    Glass {
        /// Transmission colour (linear RGB).
        tint: Vec3,
        /// Roughness.
        ggx: Ggx,
        /// Index of refraction, inside over outside.
        eta: f32,
    },
}

/// A sampled direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// The direction toward the light, local.
    pub wi: Vec3,
    /// The BSDF value for (wo, wi), without the cosine.
    pub f: Vec3,
    /// Solid-angle density of having drawn `wi`.
    pub pdf: f32,
}

/// Probability of sampling the plastic's coating rather than its base, from
/// the coating's reflectance `f` toward the viewer.
fn plastic_specular_probability(base: Vec3, f: f32) -> f32 {
    let diffuse = (1.0 - f) * base.luminance();
    (f / (f + diffuse).max(1e-6)).clamp(0.1, 0.9)
}

impl Lobe {
    /// The BSDF value and the density [`Lobe::sample`] would give `wi`.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        match *self {
            Lobe::Plastic { base, ggx, eta } => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return (Vec3::ZERO, 0.0);
                }
                let wm = (wo + wi).normalised();
                let f = fresnel_dielectric(wo.dot(wm), eta);
                let spec = ggx.d(wm) * ggx.g(wo, wi) * f / (4.0 * wo.z * wi.z);
                let f_o = fresnel_dielectric(wo.z, eta);
                let through = (1.0 - f_o) * (1.0 - fresnel_dielectric(wi.z, eta));
                let value = base * (FRAC_1_PI * through) + Vec3::splat(spec);
                let ps = plastic_specular_probability(base, f_o);
                let pdf = ps * ggx.visible_pdf(wo, wm) / (4.0 * wo.dot(wm))
                    + (1.0 - ps) * wi.z * FRAC_1_PI;
                (value, pdf)
            }
            Lobe::Metal { f0, ggx } => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return (Vec3::ZERO, 0.0);
                }
                let wm = (wo + wi).normalised();
                let f = fresnel_schlick(f0, wo.dot(wm));
                let value = f * (ggx.d(wm) * ggx.g(wo, wi) / (4.0 * wo.z * wi.z));
                (value, ggx.visible_pdf(wo, wm) / (4.0 * wo.dot(wm)))
            }
            Lobe::Glass { tint, ggx, eta } => glass_eval(tint, ggx, eta, wo, wi),
        }
    }

    /// Draws `wi` for `wo` from two uniform numbers `u` and one `uc` (which
    /// picks between sub-lobes). `None` when the draw leaves no contribution.
    pub fn sample(&self, wo: Vec3, u: [f32; 2], uc: f32) -> Option<BsdfSample> {
        let wi = match *self {
            Lobe::Plastic { base, ggx, eta } => {
                if wo.z <= 0.0 {
                    return None;
                }
                if uc < plastic_specular_probability(base, fresnel_dielectric(wo.z, eta)) {
                    reflect(wo, ggx.sample_visible(wo, u))
                } else {
                    crate::sampling::cosine_hemisphere(u)
                }
            }
            Lobe::Metal { ggx, .. } => {
                if wo.z <= 0.0 {
                    return None;
                }
                reflect(wo, ggx.sample_visible(wo, u))
            }
            Lobe::Glass { ggx, eta, .. } => {
                // Sample the microfacet on the side wo is on.
                let flip = if wo.z < 0.0 { -1.0 } else { 1.0 };
                let wm = ggx.sample_visible(wo * flip, u) * flip;
                let r = fresnel_dielectric(wo.dot(wm), eta);
                if uc < r {
                    reflect(wo, wm)
                } else {
                    refract(wo, wm, eta)?.0
                }
            }
        };
        let (f, pdf) = self.eval(wo, wi);
        (pdf > 0.0 && f.max_elem() > 0.0 && f.is_finite()).then_some(BsdfSample { wi, f, pdf })
    }
}

/// Rough dielectric: value and density (Walter et al. 2007, in the form of
/// PBRT v4: the generalised half vector, back-facing microfacets rejected,
/// radiance scaled by 1/eta² on refraction).
fn glass_eval(tint: Vec3, ggx: Ggx, eta: f32, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
    let (cos_o, cos_i) = (wo.z, wi.z);
    if cos_o == 0.0 || cos_i == 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    let reflection = cos_o * cos_i > 0.0;
    let etap = if reflection {
        1.0
    } else if cos_o > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let wm = wi * etap + wo;
    if wm.dot(wm) == 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    let mut wm = wm.normalised();
    if wm.z < 0.0 {
        wm = -wm;
    }
    if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    let r = fresnel_dielectric(wo.dot(wm), eta);
    let t = 1.0 - r;
    let d_visible = ggx.visible_pdf(if cos_o < 0.0 { -wo } else { wo }, wm);
    if reflection {
        let value = ggx.d(wm) * ggx.g(wo, wi) * r / (4.0 * cos_i * cos_o).abs();
        let pdf = d_visible / (4.0 * wo.dot(wm).abs()) * r;
        (Vec3::splat(value), pdf)
    } else {
        let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
        let value = ggx.d(wm)
            * t
            * ggx.g(wo, wi)
            * (wi.dot(wm) * wo.dot(wm) / (cos_i * cos_o * denom)).abs()
            / (etap * etap);
        let pdf = d_visible * wi.dot(wm).abs() / denom * t;
        (tint * value, pdf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{uniform_sphere, Pcg32};

    fn lobes() -> Vec<Lobe> {
        let mut v = vec![];
        for roughness in [0.05, 0.3, 0.8] {
            let ggx = Ggx::from_roughness(roughness);
            v.push(Lobe::Plastic {
                base: Vec3::ONE,
                ggx,
                eta: 1.5,
            });
            v.push(Lobe::Metal { f0: Vec3::ONE, ggx });
            v.push(Lobe::Glass {
                tint: Vec3::ONE,
                ggx,
                eta: 1.5,
            });
        }
        v
    }

    fn directions() -> Vec<Vec3> {
        [0.99f32, 0.7, 0.3, 0.05]
            .iter()
            .map(|&z| Vec3::new((1.0 - z * z).sqrt(), 0.0, z))
            .collect()
    }

    #[test]
    fn sampling_conserves_energy_and_agrees_with_eval() {
        // Albedo estimate E[f cos / pdf] <= 1 for every lobe, incidence and
        // roughness; each sample's (f, pdf) equals eval's.
        for lobe in lobes() {
            for wo in directions() {
                let mut rng = Pcg32::new(1, 2);
                let n = 100_000;
                let mut albedo = 0f64;
                for _ in 0..n {
                    let Some(s) = lobe.sample(wo, rng.next_2d(), rng.next_f32()) else {
                        continue;
                    };
                    let (f, pdf) = lobe.eval(wo, s.wi);
                    assert!(
                        (f - s.f).length() <= 1e-4 * f.length()
                            && (pdf - s.pdf).abs() <= 1e-4 * pdf
                    );
                    albedo += (s.f.y * s.wi.z.abs() / s.pdf) as f64;
                }
                let albedo = albedo / n as f64;
                assert!(albedo <= 1.01, "{lobe:?} at {wo:?}: albedo {albedo}");
                assert!(albedo > 0.3, "{lobe:?} at {wo:?}: albedo {albedo}");
            }
        }
    }

    #[test]
    fn densities_integrate_to_at_most_one() {
        for lobe in lobes().into_iter().filter(|l| !matches!(l, Lobe::Plastic { ggx, .. } | Lobe::Metal { ggx, .. } | Lobe::Glass { ggx, .. } if ggx.alpha < 0.01001)) {
            let wo = Vec3::new(0.6, 0.0, 0.8);
            let mut rng = Pcg32::new(3, 4);
            let n = 400_000;
            let total: f64 = (0..n)
                .map(|_| lobe.eval(wo, uniform_sphere(rng.next_2d())).1 as f64 * 4.0 * std::f64::consts::PI)
                .sum::<f64>()
                / n as f64;
            assert!(total <= 1.03 && total > 0.5, "{lobe:?}: {total}");
        }
    }

    #[test]
    fn a_white_lambertian_base_under_an_index_of_one_reflects_everything() {
        let lobe = Lobe::Plastic {
            base: Vec3::ONE,
            ggx: Ggx::from_roughness(0.5),
            eta: 1.0,
        };
        let mut rng = Pcg32::new(8, 0);
        let wo = Vec3::new(0.0, 0.6, 0.8);
        let n = 100_000;
        let albedo: f64 = (0..n)
            .filter_map(|_| lobe.sample(wo, rng.next_2d(), rng.next_f32()))
            .map(|s| (s.f.x * s.wi.z / s.pdf) as f64)
            .sum::<f64>()
            / n as f64;
        assert!((albedo - 1.0).abs() < 1e-3, "{albedo}");
    }
}
