//! An edge-aware denoiser for low sample counts: the edge-avoiding à-trous
//! wavelet filter (Dammertz et al. 2010) on the illumination (radiance
//! divided by the primary hit's base colour, so textures stay sharp),
//! guided by the normal and base-colour buffers the path tracer writes. The
//! annotation is never filtered.

use crate::integrator::Rendered;
use crate::math::Vec3;
use rayon::prelude::*;

/// Filter passes (the kernel's reach doubles each pass: 5, 9, 17, 33 px).
pub const PASSES: u32 = 4;
/// Width of the illumination weight from the second pass on, relative to
/// the pixels' brightness; halves each pass.
const SIGMA_ILLUMINATION: f32 = 1.0;
/// Width of the normal weight (squared distance of unit normals).
const SIGMA_NORMAL: f32 = 0.1;
/// Width of the base-colour weight.
const SIGMA_ALBEDO: f32 = 0.1;
/// The B3-spline taps of the à-trous kernel.
const TAPS: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// The base colour radiance is divided by (no division where nothing was
/// hit, or the colour is black).
fn demodulator(albedo: Vec3) -> Vec3 {
    if albedo.max_elem() <= 0.0 {
        Vec3::ONE
    } else {
        albedo.max(Vec3::splat(0.01))
    }
}

/// The denoised radiance of a render.
pub fn denoise(r: &Rendered) -> Vec<Vec3> {
    let (w, h) = (r.width, r.height);
    let demod: Vec<Vec3> = r.albedo.iter().map(|&a| demodulator(a)).collect();
    let mut light: Vec<Vec3> = r
        .radiance
        .iter()
        .zip(&demod)
        .map(|(&c, &a)| Vec3::new(c.x / a.x, c.y / a.y, c.z / a.z))
        .collect();
    for pass in 0..PASSES {
        let step = 1i64 << pass;
        // The first pass has no illumination term: a pixel whose few
        // samples all missed the light would otherwise find no neighbour
        // alike and stay a dark speckle. Later passes compare the smoothed
        // light, with a narrowing tolerance.
        let sigma = if pass == 0 {
            f32::INFINITY
        } else {
            SIGMA_ILLUMINATION / (1 << (pass - 1)) as f32
        };
        let source = &light;
        light = (0..w * h)
            .into_par_iter()
            .map(|p| {
                let (px, py) = ((p % w) as i64, (p / w) as i64);
                let (cp, np, ap) = (source[p], r.normal[p], r.albedo[p]);
                let (mut sum, mut total) = (Vec3::ZERO, 0.0);
                for (j, ky) in TAPS.iter().enumerate() {
                    let qy = py + (j as i64 - 2) * step;
                    if qy < 0 || qy >= h as i64 {
                        continue;
                    }
                    for (i, kx) in TAPS.iter().enumerate() {
                        let qx = px + (i as i64 - 2) * step;
                        if qx < 0 || qx >= w as i64 {
                            continue;
                        }
                        let q = qy as usize * w + qx as usize;
                        let (cq, nq, aq) = (source[q], r.normal[q], r.albedo[q]);
                        let dc = cp - cq;
                        let scale = (cp + cq).mul_elem(cp + cq).max_elem() * 0.25 + 1e-4;
                        let dn = np - nq;
                        let da = ap - aq;
                        let weight = kx
                            * ky
                            * (-dc.dot(dc) / (scale * sigma * sigma)
                                - dn.dot(dn) / SIGMA_NORMAL
                                - da.dot(da) / (SIGMA_ALBEDO * SIGMA_ALBEDO))
                                .exp();
                        sum += cq * weight;
                        total += weight;
                    }
                }
                sum / total
            })
            .collect();
    }
    light
        .iter()
        .zip(&demod)
        .map(|(&l, &a)| l.mul_elem(a))
        .collect()
}
