//! Procedural shapes with texture coordinates: sphere, torus, box, cylinder,
//! cone, superquadric and a displaced blob. Each is built around the origin
//! with a bounding radius near 1; scenes scale them.

use crate::math::Vec3;
use crate::mesh::Mesh;
use crate::sampling::{uniform_sphere, Pcg32};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::f32::consts::PI;

/// A procedural shape and its parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "shape", rename_all = "snake_case")]
pub enum Primitive {
    /// The unit sphere.
    Sphere,
    /// A ring: major radius 1, tube radius `minor` (0..1).
    Torus {
        /// Tube radius relative to the ring's.
        minor: f32,
    },
    /// A box with half-sides `size`.
    Box {
        /// Half-extents along x, y, z.
        size: [f32; 3],
    },
    /// A closed cylinder along z: radius 1, height `height`.
    Cylinder {
        /// Height relative to the radius.
        height: f32,
    },
    /// A closed cone along z: base radius 1, height `height`.
    Cone {
        /// Height relative to the base radius.
        height: f32,
    },
    /// Barr's superquadric `|x|^(2/e2) ... `: exponents `e1` (latitude) and
    /// `e2` (longitude); 1,1 is a sphere, small values are boxy, 2 is a
    /// double cone / octahedron.
    Superquadric {
        /// North-south exponent.
        e1: f32,
        /// East-west exponent.
        e2: f32,
    },
    /// A sphere pushed in and out by `bumps` smooth random bumps of relative
    /// height up to `amplitude`, drawn from `seed`.
    Blob {
        /// Seed of the bumps.
        seed: u64,
        /// Number of bumps.
        bumps: u32,
        /// Largest relative height of a bump.
        amplitude: f32,
    },
}

/// Grid resolution of the curved primitives (segments around).
const SEGMENTS: usize = 96;

impl Primitive {
    /// The triangle mesh of the shape, with normals and UVs.
    pub fn mesh(&self) -> Mesh {
        match *self {
            Primitive::Sphere => parametric(SEGMENTS, SEGMENTS / 2, |u, v| {
                let (theta, phi) = (PI * v, 2.0 * PI * u);
                Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    -theta.cos(),
                )
            }),
            Primitive::Torus { minor } => parametric(SEGMENTS, SEGMENTS / 2, move |u, v| {
                let (a, b) = (2.0 * PI * u, 2.0 * PI * v);
                let r = 1.0 + minor * b.cos();
                Vec3::new(r * a.cos(), r * a.sin(), minor * b.sin())
            }),
            Primitive::Box { size } => box_mesh(size),
            Primitive::Cylinder { height } => {
                let h = height / 2.0;
                let mut m = parametric(SEGMENTS, 8, |u, v| {
                    let a = 2.0 * PI * u;
                    Vec3::new(a.cos(), a.sin(), -h + 2.0 * h * v)
                });
                m.append(&disk(h, 1.0, true));
                m.append(&disk(-h, 1.0, false));
                m
            }
            Primitive::Cone { height } => {
                let h = height / 2.0;
                let mut m = parametric(SEGMENTS, 8, |u, v| {
                    let a = 2.0 * PI * u;
                    // The apex is a ring of radius ~0 so UVs stay defined.
                    let r = (1.0 - v).max(1e-4);
                    Vec3::new(r * a.cos(), r * a.sin(), -h + 2.0 * h * v)
                });
                m.append(&disk(-h, 1.0, false));
                m
            }
            Primitive::Superquadric { e1, e2 } => {
                let f = |w: f32, e: f32| w.signum() * w.abs().powf(e);
                parametric(SEGMENTS, SEGMENTS / 2, move |u, v| {
                    let (eta, omega) = (PI * (v - 0.5), 2.0 * PI * u - PI);
                    let ce = f(eta.cos(), e1);
                    Vec3::new(
                        ce * f(omega.cos(), e2),
                        ce * f(omega.sin(), e2),
                        f(eta.sin(), e1),
                    )
                })
            }
            Primitive::Blob {
                seed,
                bumps,
                amplitude,
            } => {
                let mut rng = Pcg32::new(seed, 0xb10b);
                let bumps: Vec<(Vec3, f32, f32)> = (0..bumps)
                    .map(|_| {
                        let dir = uniform_sphere(rng.next_2d());
                        let height = amplitude * (2.0 * rng.next_f32() - 1.0);
                        let sharpness = 2.0 + 10.0 * rng.next_f32();
                        (dir, height, sharpness)
                    })
                    .collect();
                parametric(SEGMENTS, SEGMENTS / 2, move |u, v| {
                    let (theta, phi) = (PI * v, 2.0 * PI * u);
                    let d = Vec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        -theta.cos(),
                    );
                    let r: f32 = 1.0
                        + bumps
                            .iter()
                            .map(|&(b, h, s)| h * (s * (d.dot(b) - 1.0)).exp())
                            .sum::<f32>();
                    d * r.max(0.2)
                })
            }
        }
    }
}

/// A square of half-side 1 in the xy plane facing +z, UVs over [0,1]².
pub fn ground_plane() -> Mesh {
    Mesh {
        positions: vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ],
        normals: vec![Vec3::Z; 4],
        uvs: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// A `(nu + 1) x (nv + 1)` vertex grid over `f(u, v)` for u, v in [0, 1],
/// with UVs (u, v), area-weighted normals, and normals averaged across
/// seams and poles (vertices at the same place) so shading has no creases.
fn parametric(nu: usize, nv: usize, f: impl Fn(f32, f32) -> Vec3) -> Mesh {
    let mut m = Mesh::default();
    for j in 0..=nv {
        for i in 0..=nu {
            let (u, v) = (i as f32 / nu as f32, j as f32 / nv as f32);
            m.positions.push(f(u, v));
            m.uvs.push([u, v]);
        }
    }
    let row = (nu + 1) as u32;
    for j in 0..nv as u32 {
        for i in 0..nu as u32 {
            let a = j * row + i;
            let (b, c, d) = (a + 1, a + row + 1, a + row);
            push_if_not_degenerate(&mut m, [a, b, c]);
            push_if_not_degenerate(&mut m, [a, c, d]);
        }
    }
    m.compute_normals();
    weld_normals(&mut m);
    m
}

fn push_if_not_degenerate(m: &mut Mesh, t: [u32; 3]) {
    let [a, b, c] = t.map(|i| m.positions[i as usize]);
    if (b - a).cross(c - a).length() > 1e-9 {
        m.triangles.push(t);
    }
}

/// Averages the normals of vertices that share a position (to 1e-5).
fn weld_normals(m: &mut Mesh) {
    let key = |p: Vec3| [p.x, p.y, p.z].map(|c| (c * 1e5).round() as i64);
    let mut sums: HashMap<[i64; 3], Vec3> = HashMap::new();
    for (p, n) in m.positions.iter().zip(&m.normals) {
        *sums.entry(key(*p)).or_default() += *n;
    }
    for (p, n) in m.positions.iter().zip(m.normals.iter_mut()) {
        let s = sums[&key(*p)].normalised();
        if s != Vec3::ZERO {
            *n = s;
        }
    }
}

/// A flat disk at height `z`, facing up or down, UVs over its square.
fn disk(z: f32, radius: f32, up: bool) -> Mesh {
    let normal = if up { Vec3::Z } else { -Vec3::Z };
    let mut m = Mesh {
        positions: vec![Vec3::new(0.0, 0.0, z)],
        normals: vec![normal],
        uvs: vec![[0.5, 0.5]],
        triangles: vec![],
    };
    for i in 0..=SEGMENTS {
        let a = 2.0 * PI * i as f32 / SEGMENTS as f32;
        let (s, c) = a.sin_cos();
        m.positions.push(Vec3::new(radius * c, radius * s, z));
        m.normals.push(normal);
        m.uvs.push([0.5 + 0.5 * c, 0.5 + 0.5 * s]);
    }
    for i in 1..=SEGMENTS as u32 {
        m.triangles
            .push(if up { [0, i, i + 1] } else { [0, i + 1, i] });
    }
    m
}

/// A box of half-extents `size` with flat faces, each face's UVs over [0,1]².
fn box_mesh(size: [f32; 3]) -> Mesh {
    let s = Vec3::from(size);
    let mut m = Mesh::default();
    // For each face: its normal and two in-plane axes (u, v) with u x v = n.
    let faces = [
        (Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::Z),
        (Vec3::new(-1.0, 0.0, 0.0), Vec3::Z, Vec3::new(0.0, 1.0, 0.0)),
        (Vec3::new(0.0, 1.0, 0.0), Vec3::Z, Vec3::new(1.0, 0.0, 0.0)),
        (Vec3::new(0.0, -1.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::Z),
        (Vec3::Z, Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)),
        (-Vec3::Z, Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 0.0, 0.0)),
    ];
    for (n, u, v) in faces {
        let base = m.positions.len() as u32;
        for (a, b) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            let p = n + u * (2.0 * a - 1.0) + v * (2.0 * b - 1.0);
            m.positions.push(p.mul_elem(s));
            m.normals.push(n);
            m.uvs.push([a, b]);
        }
        m.triangles.push([base, base + 1, base + 2]);
        m.triangles.push([base, base + 2, base + 3]);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Signed volume by the divergence theorem: positive when every face
    /// is counter-clockwise seen from outside.
    fn volume(m: &Mesh) -> f32 {
        m.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    fn all() -> Vec<Primitive> {
        vec![
            Primitive::Sphere,
            Primitive::Torus { minor: 0.3 },
            Primitive::Box {
                size: [1.0, 0.5, 0.25],
            },
            Primitive::Cylinder { height: 2.0 },
            Primitive::Cone { height: 2.0 },
            Primitive::Superquadric { e1: 0.3, e2: 0.3 },
            Primitive::Blob {
                seed: 4,
                bumps: 6,
                amplitude: 0.3,
            },
        ]
    }

    #[test]
    fn primitives_are_valid_closed_and_outward() {
        for p in all() {
            let m = p.mesh();
            m.validate().unwrap_or_else(|e| panic!("{p:?}: {e}"));
            assert!(volume(&m) > 0.0, "{p:?} faces inward");
            // Normals agree with the face orientation on average.
            let agree = m.triangles.iter().filter(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                let face = (b - a).cross(c - a);
                t.iter().all(|&i| m.normals[i as usize].dot(face) > 0.0)
            });
            assert!(
                agree.count() as f32 > 0.95 * m.triangles.len() as f32,
                "{p:?}"
            );
        }
    }

    #[test]
    fn volumes_match_the_formulas() {
        let sphere = volume(&Primitive::Sphere.mesh());
        assert!((sphere - 4.0 / 3.0 * PI).abs() < 0.01 * sphere, "{sphere}");
        let torus = volume(&Primitive::Torus { minor: 0.3 }.mesh());
        let exact = 2.0 * PI * PI * 0.09;
        assert!((torus - exact).abs() < 0.01 * exact, "{torus}");
        let cube = volume(
            &Primitive::Box {
                size: [1.0, 0.5, 0.25],
            }
            .mesh(),
        );
        assert!((cube - 1.0).abs() < 1e-5);
        let cyl = volume(&Primitive::Cylinder { height: 2.0 }.mesh());
        assert!((cyl - 2.0 * PI).abs() < 0.01 * cyl);
        let cone = volume(&Primitive::Cone { height: 3.0 }.mesh());
        assert!((cone - PI).abs() < 0.01 * cone);
    }
}
