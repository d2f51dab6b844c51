//! The path tracer: unidirectional paths from the camera with next-event
//! estimation (HDRI by importance sampling, combined with BSDF sampling by
//! multiple importance sampling; point and spot lights directly), Russian
//! roulette, stratified pixel samples and a clamp on indirect light against
//! fireflies. Beside the image it accumulates, from the primary hits, the
//! fraction of each main-object material per pixel: the exact soft
//! annotation, anti-aliased like the image.

use crate::bsdf::Lobe;
use crate::bvh::{Bvh, Triangle};
use crate::math::{Frame, Ray, Vec3};
use crate::sampling::{power_heuristic, stratified_2d, Pcg32};
use crate::scene::LoadedScene;
use crate::texture::linear_to_srgb;
use rayon::prelude::*;

/// Largest indirect contribution a single sample may add (per channel),
/// like Cycles' default "clamp indirect" of 10.
pub const INDIRECT_CLAMP: f32 = 10.0;
/// Bounces before Russian roulette starts.
const ROULETTE_AFTER: u32 = 3;

/// A rendered image and its buffers, per pixel, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Rendered {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Mean linear radiance.
    pub radiance: Vec<Vec3>,
    /// Mean base colour at the primary hit (black where nothing is hit).
    pub albedo: Vec<Vec3>,
    /// Mean shading normal at the primary hit.
    pub normal: Vec<Vec3>,
    /// For each annotated material, the fraction of the pixel's samples
    /// whose primary hit is on a main object, weighted by that material's
    /// share of the surface there.
    pub fractions: Vec<Vec<f32>>,
    /// Fraction of the pixel's samples whose primary hit is on a main object
    /// (the sum of the fractions).
    pub roi: Vec<f32>,
    /// Scene material index of each annotation channel.
    pub annotated: Vec<usize>,
}

/// One pixel's sums.
#[derive(Clone, Debug)]
struct PixelSums {
    radiance: Vec3,
    albedo: Vec3,
    normal: Vec3,
    fractions: Vec<f32>,
    roi: f32,
}

/// The scene's triangles for the BVH.
pub fn scene_bvh(scene: &LoadedScene) -> Bvh {
    let m = &scene.mesh;
    let tris: Vec<Triangle> = m
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            Triangle::new(a, b, c)
        })
        .collect();
    Bvh::build(&tris)
}

/// Renders the scene with its own settings.
pub fn render(scene: &LoadedScene) -> Result<Rendered, crate::SceneError> {
    let d = &scene.description;
    let (w, h) = (d.width as usize, d.height as usize);
    let rays = d.camera.rays(d.width, d.height)?;
    let bvh = scene_bvh(scene);
    let mut channel_of = vec![None; scene.materials.len()];
    for (k, &m) in scene.annotated.iter().enumerate() {
        channel_of[m] = Some(k);
    }
    let tracer = Tracer {
        scene,
        bvh: &bvh,
        channel_of: &channel_of,
        epsilon: 1e-4 * (1.0 + bvh.bounds().max.max(-bvh.bounds().min).max_elem().min(1e6)),
    };
    let rows: Vec<Vec<PixelSums>> = (0..h)
        .into_par_iter()
        .map(|y| {
            // Layout weights of a hit, reused by every path of the row.
            let mut weights: Vec<(usize, f32)> = Vec::with_capacity(8);
            (0..w)
                .map(|x| {
                    let mut rng = Pcg32::new(d.seed, (y * w + x) as u64);
                    let mut sums = PixelSums {
                        radiance: Vec3::ZERO,
                        albedo: Vec3::ZERO,
                        normal: Vec3::ZERO,
                        fractions: vec![0.0; scene.annotated.len()],
                        roi: 0.0,
                    };
                    for s in 0..d.spp {
                        let [jx, jy] = stratified_2d(s, d.spp, rng.next_2d());
                        let ray = rays.ray(x as f32 + jx, y as f32 + jy);
                        tracer.sample(ray, &mut rng, &mut sums, &mut weights);
                    }
                    sums
                })
                .collect()
        })
        .collect();
    let n = 1.0 / d.spp as f32;
    let pixels = rows.into_iter().flatten();
    let mut out = Rendered {
        width: w,
        height: h,
        radiance: Vec::with_capacity(w * h),
        albedo: Vec::with_capacity(w * h),
        normal: Vec::with_capacity(w * h),
        fractions: vec![Vec::with_capacity(w * h); scene.annotated.len()],
        roi: Vec::with_capacity(w * h),
        annotated: scene.annotated.clone(),
    };
    for p in pixels {
        out.radiance.push(p.radiance * n);
        out.albedo.push(p.albedo * n);
        out.normal.push(p.normal.normalised());
        for (f, v) in out.fractions.iter_mut().zip(&p.fractions) {
            f.push(v * n);
        }
        out.roi.push(p.roi * n);
    }
    if d.denoise {
        out.radiance = crate::denoise::denoise(&out);
    }
    Ok(out)
}

struct Tracer<'a> {
    scene: &'a LoadedScene,
    bvh: &'a Bvh,
    channel_of: &'a [Option<usize>],
    epsilon: f32,
}

impl Tracer<'_> {
    /// A ray origin just off the surface at `p`, on the side of `dir`.
    #[inline]
    fn offset(&self, p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
        let side = if dir.dot(ng) >= 0.0 { 1.0 } else { -1.0 };
        p + ng * (self.epsilon * side)
    }

    /// Traces one camera path, adding into the pixel's sums.
    fn sample(
        &self,
        mut ray: Ray,
        rng: &mut Pcg32,
        sums: &mut PixelSums,
        weights: &mut Vec<(usize, f32)>,
    ) {
        let scene = self.scene;
        let d = &scene.description;
        let env = &scene.environment;
        let mut throughput = Vec3::ONE;
        let mut radiance = Vec3::ZERO;
        let mut indirect = Vec3::ZERO;
        let mut bsdf_pdf = 0.0f32;
        for bounce in 0..=d.max_bounces {
            let mut add = |v: Vec3| {
                if bounce == 0 {
                    radiance += v;
                } else {
                    indirect += v;
                }
            };
            let Some(hit) = self.bvh.intersect(&ray, 0.0, f32::INFINITY) else {
                // Camera rays see the smooth map; paths see the piecewise
                // constant one that light sampling draws from.
                let (le, w) = if bounce == 0 {
                    (env.radiance(ray.dir), 1.0)
                } else {
                    let (le, light_pdf) = env.radiance_and_pdf(ray.dir);
                    (le, power_heuristic(bsdf_pdf, light_pdf))
                };
                add(throughput.mul_elem(le) * w);
                break;
            };
            let p = ray.at(hit.t);
            let sp = scene.surface_point(&hit, p);
            let object = &scene.objects[sp.object];
            weights.clear();
            scene.layout_weights(&object.surface, sp.uv, 1.0, weights);
            let total: f32 = weights.iter().map(|w| w.1).sum();
            if bounce == 0 && object.main {
                for &(m, w) in weights.iter() {
                    if let Some(k) = self.channel_of[m] {
                        sums.fractions[k] += w / total;
                    }
                }
                sums.roi += 1.0;
            }
            // Draw one material by its weight.
            let mut u = rng.next_f32() * total;
            let material = weights
                .iter()
                .find(|(_, w)| {
                    u -= w;
                    u < 0.0
                })
                .unwrap_or(&weights[weights.len() - 1])
                .0;
            let material = &scene.materials[material];
            let ms = material.at(&sp);
            let lobe = material.lobe(&ms, rng.next_f32());
            if bounce == 0 {
                sums.albedo += ms.base;
                sums.normal += ms.normal;
            }
            let wo_world = -ray.dir;
            let (mut ng, mut ns) = (sp.geometric_normal, ms.normal);
            // Opaque surfaces are two-sided; glass keeps its outside.
            if !matches!(lobe, Lobe::Glass { .. }) && ng.dot(wo_world) < 0.0 {
                ng = -ng;
                ns = -ns;
            }
            if ns.dot(ng) <= 0.0 {
                ns = ng;
            }
            let frame = Frame::from_normal(ns);
            let wo = frame.to_local(wo_world);
            if bounce == d.max_bounces {
                break;
            }
            // Next event: the environment, weighted against BSDF sampling.
            if let Some((dir, le, light_pdf)) = env.sample(rng.next_2d()) {
                let wi = frame.to_local(dir);
                if (dir.dot(ng) > 0.0) == (wi.z > 0.0) {
                    let (f, pdf) = lobe.eval(wo, wi);
                    if f.max_elem() > 0.0 {
                        let shadow = Ray {
                            origin: self.offset(p, ng, dir),
                            dir,
                        };
                        if !self.bvh.occluded(&shadow, 0.0, f32::INFINITY) {
                            let w = power_heuristic(light_pdf, pdf);
                            add(throughput.mul_elem(f).mul_elem(le) * (wi.z.abs() * w / light_pdf));
                        }
                    }
                }
            }
            // Next event: point and spot lights (delta lights, no MIS).
            for light in &d.lights {
                let Some((dir, dist, li)) = light.illuminate(p) else {
                    continue;
                };
                let wi = frame.to_local(dir);
                if (dir.dot(ng) > 0.0) != (wi.z > 0.0) {
                    continue;
                }
                let (f, _) = lobe.eval(wo, wi);
                if f.max_elem() <= 0.0 {
                    continue;
                }
                let shadow = Ray {
                    origin: self.offset(p, ng, dir),
                    dir,
                };
                if !self.bvh.occluded(&shadow, 0.0, dist * (1.0 - 1e-4)) {
                    add(throughput.mul_elem(f).mul_elem(li) * wi.z.abs());
                }
            }
            // Continue the path by sampling the BSDF.
            let Some(s) = lobe.sample(wo, rng.next_2d(), rng.next_f32()) else {
                break;
            };
            let dir = frame.to_world(s.wi);
            if (dir.dot(ng) > 0.0) != (s.wi.z > 0.0) {
                break;
            }
            throughput = throughput.mul_elem(s.f) * (s.wi.z.abs() / s.pdf);
            bsdf_pdf = s.pdf;
            ray = Ray {
                origin: self.offset(p, ng, dir),
                dir,
            };
            if bounce >= ROULETTE_AFTER {
                let q = throughput.max_elem().min(0.95);
                if rng.next_f32() >= q {
                    break;
                }
                throughput = throughput / q;
            }
        }
        let clamp = INDIRECT_CLAMP;
        sums.radiance += radiance + indirect.min(Vec3::splat(clamp));
    }
}

/// Filmic tone curve (Narkowicz's fit of the ACES reference transform),
/// applied per channel after `exposure_ev` stops, then sRGB encoding.
pub fn tone_map(
    radiance: &[Vec3],
    width: usize,
    height: usize,
    exposure_ev: f32,
) -> image::RgbImage {
    let k = 2f32.powf(exposure_ev);
    let curve = |x: f32| {
        let x = (x * k).max(0.0);
        (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)
    };
    let raw: Vec<u8> = radiance
        .iter()
        .flat_map(|c| {
            c.to_array()
                .map(|v| (linear_to_srgb(curve(v)) * 255.0 + 0.5) as u8)
        })
        .collect();
    image::RgbImage::from_raw(width as u32, height as u32, raw).expect("one pixel per radiance")
}
