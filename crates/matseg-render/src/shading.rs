//! What a ray sees where it hits: the surface's position, normals, texture
//! coordinates and tangent frame; the material weights of its layout; and
//! the scattering lobe of the material drawn there.

use crate::bsdf::Lobe;
use crate::bvh::Hit;
use crate::math::{Frame, Vec3};
use crate::microfacet::Ggx;
use crate::scene::{Layout, LoadedMaterial, LoadedScene, SceneMap};

/// Geometry at a hit point, world space.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    /// Position.
    pub position: Vec3,
    /// Unit face normal, oriented like the mesh's vertex normals.
    pub geometric_normal: Vec3,
    /// Unit interpolated vertex normal.
    pub shading_normal: Vec3,
    /// Unit direction of increasing u on the surface (or any tangent).
    pub tangent: Vec3,
    /// Whether the UV mapping is mirrored (bitangent = -(n x t)).
    pub mirrored: bool,
    /// Texture coordinates.
    pub uv: [f32; 2],
    /// The object hit.
    pub object: usize,
}

impl LoadedScene {
    /// The surface point of a BVH hit.
    pub fn surface_point(&self, hit: &Hit, position: Vec3) -> SurfacePoint {
        let m = &self.mesh;
        let tri = m.triangles[hit.triangle as usize];
        let [a, b, c] = tri.map(|i| i as usize);
        let b0 = 1.0 - hit.b1 - hit.b2;
        let (e1, e2) = (
            m.positions[b] - m.positions[a],
            m.positions[c] - m.positions[a],
        );
        let mut geometric_normal = e1.cross(e2).normalised();
        let shading_normal =
            (m.normals[a] * b0 + m.normals[b] * hit.b1 + m.normals[c] * hit.b2).normalised();
        if geometric_normal.dot(shading_normal) < 0.0 {
            geometric_normal = -geometric_normal;
        }
        let [ua, ub, uc] = [m.uvs[a], m.uvs[b], m.uvs[c]];
        let uv = [
            ua[0] * b0 + ub[0] * hit.b1 + uc[0] * hit.b2,
            ua[1] * b0 + ub[1] * hit.b1 + uc[1] * hit.b2,
        ];
        // dp/du from the triangle's UV differences.
        let (d1, d2) = (
            [ub[0] - ua[0], ub[1] - ua[1]],
            [uc[0] - ua[0], uc[1] - ua[1]],
        );
        let det = d1[0] * d2[1] - d1[1] * d2[0];
        let tangent = if det.abs() > 1e-12 {
            ((e1 * d2[1] - e2 * d1[1]) / det).normalised()
        } else {
            Frame::from_normal(shading_normal).s
        };
        SurfacePoint {
            position,
            geometric_normal,
            shading_normal,
            tangent,
            mirrored: det < 0.0,
            uv,
            object: self.triangle_object[hit.triangle as usize] as usize,
        }
    }

    /// The material weights of `layout` at surface coordinates `uv`, added
    /// (times `scale`) into `out` as (material, weight) pairs.
    pub fn layout_weights(
        &self,
        layout: &Layout,
        uv: [f32; 2],
        scale: f32,
        out: &mut Vec<(usize, f32)>,
    ) {
        if scale <= 0.0 {
            return;
        }
        match layout {
            Layout::Material(m) => match out.iter_mut().find(|(k, _)| k == m) {
                Some((_, w)) => *w += scale,
                None => out.push((*m, scale)),
            },
            Layout::Split {
                map,
                placement,
                ramp,
                below,
                above,
            } => {
                let [u, v] = placement.apply(uv);
                let SceneMap { map, scale: norm } = &self.maps[*map];
                let t = ramp.apply((map.levels.scalar(u, v) * norm).min(1.0));
                self.layout_weights(below, uv, scale * (1.0 - t), out);
                self.layout_weights(above, uv, scale * t, out);
            }
        }
    }
}

/// The shading inputs of a material at a point.
#[derive(Clone, Copy, Debug)]
pub struct MaterialSample {
    /// Base colour, linear.
    pub base: Vec3,
    /// Perceptual roughness.
    pub roughness: f32,
    /// Metalness.
    pub metallic: f32,
    /// The shading normal after normal or bump mapping.
    pub normal: Vec3,
}

impl LoadedMaterial {
    /// Looks up the maps at surface point `sp`.
    pub fn at(&self, sp: &SurfacePoint) -> MaterialSample {
        let d = &self.description;
        let [u, v] = d.placement.apply(sp.uv);
        let base = self
            .maps
            .colour
            .as_ref()
            .map_or(d.base_colour, |t| Vec3::from(t.linear_rgb(u, v)));
        let roughness = self
            .maps
            .roughness
            .as_ref()
            .map_or(d.roughness, |t| t.scalar(u, v));
        let metallic = self
            .maps
            .metalness
            .as_ref()
            .map_or(d.metallic, |t| t.scalar(u, v));
        let n = sp.shading_normal;
        let frame = Frame::from_normal_tangent(n, sp.tangent);
        let bitangent = if sp.mirrored { -frame.t } else { frame.t };
        let normal = if let Some(nm) = &self.maps.normal {
            let [x, y, z] = nm.raw_rgb(u, v).map(|c| 2.0 * c - 1.0);
            let mapped = (frame.s * x + bitangent * y + n * z.max(0.05)).normalised();
            if mapped.is_finite() && mapped != Vec3::ZERO {
                mapped
            } else {
                n
            }
        } else if let Some(h) = &self.maps.height {
            // Central differences over one texel.
            let (du, dv) = (1.0 / h.width() as f32, 1.0 / h.height() as f32);
            let hu = (h.scalar(u + du, v) - h.scalar(u - du, v)) / (2.0 * du);
            let hv = (h.scalar(u, v + dv) - h.scalar(u, v - dv)) / (2.0 * dv);
            (n - (frame.s * hu + bitangent * hv) * d.bump).normalised()
        } else {
            n
        };
        MaterialSample {
            base,
            roughness,
            metallic,
            normal,
        }
    }

    /// The lobe drawn for this material with uniform `u`: metal with
    /// probability `metallic`, else glass with probability `transmission`,
    /// else plastic.
    pub fn lobe(&self, s: &MaterialSample, u: f32) -> Lobe {
        let d = &self.description;
        let ggx = Ggx::from_roughness(s.roughness);
        if u < s.metallic {
            Lobe::Metal { f0: s.base, ggx }
        } else if u < s.metallic + (1.0 - s.metallic) * d.transmission {
            Lobe::Glass {
                tint: s.base,
                ggx,
                eta: d.ior,
            }
        } else {
            Lobe::Plastic {
                base: s.base,
                ggx,
                eta: d.ior,
            }
        }
    }
}
