//! Triangle meshes with per-vertex normals and texture coordinates, and the
//! UV projections for meshes that come without them.

use crate::math::{Aabb, Transform, Vec3};
use serde::{Deserialize, Serialize};
use std::f32::consts::PI;

/// An indexed triangle mesh. `normals` and `uvs` are per vertex, as long as
/// `positions`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals.
    pub normals: Vec<Vec3>,
    /// Texture coordinates.
    pub uvs: Vec<[f32; 2]>,
    /// Vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

/// How to give texture coordinates to a mesh that has none.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UvProjection {
    /// Each vertex projected along its normal's dominant axis onto the
    /// matching face of the bounding box (triplanar-like). Seams where the
    /// axis changes.
    Box,
    /// Longitude and latitude about the bounding box's centre.
    Sphere,
}

impl Mesh {
    /// The axis-aligned bounding box of the vertices.
    pub fn bounds(&self) -> Aabb {
        self.positions.iter().fold(Aabb::EMPTY, |b, &p| b.grow(p))
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.positions.len() * (2 * std::mem::size_of::<Vec3>() + 8) + self.triangles.len() * 12
    }

    /// Distance from the bounding box's centre to the farthest vertex.
    pub fn bounding_radius(&self) -> f32 {
        let c = self.bounds().centre();
        self.positions
            .iter()
            .map(|&p| (p - c).length())
            .fold(0.0, f32::max)
    }

    /// Per-vertex normals as the area-weighted mean of the adjacent faces'
    /// normals (replaces any existing ones).
    pub fn compute_normals(&mut self) {
        let mut normals = vec![Vec3::ZERO; self.positions.len()];
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            // The cross product's length is twice the area: area weighting.
            let n = (b - a).cross(c - a);
            for &i in t {
                normals[i as usize] += n;
            }
        }
        self.normals = normals
            .into_iter()
            .map(|n| {
                let n = n.normalised();
                if n == Vec3::ZERO {
                    Vec3::Z
                } else {
                    n
                }
            })
            .collect();
    }

    /// Gives texture coordinates by `projection`, scaled so one unit of UV
    /// spans the mesh's largest bounding-box side.
    pub fn project_uvs(&mut self, projection: UvProjection) {
        if self.normals.len() != self.positions.len() {
            self.compute_normals();
        }
        let b = self.bounds();
        let c = b.centre();
        let size = (b.max - b.min).max_elem().max(1e-12);
        self.uvs = self
            .positions
            .iter()
            .zip(&self.normals)
            .map(|(&p, &n)| {
                let q = (p - c) / size;
                match projection {
                    UvProjection::Box => {
                        let a = Vec3::new(n.x.abs(), n.y.abs(), n.z.abs());
                        if a.x >= a.y && a.x >= a.z {
                            [q.y + 0.5, q.z + 0.5]
                        } else if a.y >= a.z {
                            [q.x + 0.5, q.z + 0.5]
                        } else {
                            [q.x + 0.5, q.y + 0.5]
                        }
                    }
                    UvProjection::Sphere => {
                        let d = q.normalised();
                        let u = 0.5 + d.y.atan2(d.x) / (2.0 * PI);
                        let v = 0.5 + d.z.clamp(-1.0, 1.0).asin() / PI;
                        [u, v]
                    }
                }
            })
            .collect();
    }

    /// Moves, turns and scales every vertex (normals follow).
    pub fn transform(&mut self, t: &Transform) {
        for p in &mut self.positions {
            *p = t.point(*p);
        }
        for n in &mut self.normals {
            *n = t.normal(*n);
        }
    }

    /// Centres the mesh on its bounding box and scales it to `radius`.
    pub fn normalise_to_radius(&mut self, radius: f32) {
        let c = self.bounds().centre();
        let r = self.bounding_radius().max(1e-12);
        let s = radius / r;
        for p in &mut self.positions {
            *p = (*p - c) * s;
        }
    }

    /// Appends `other`'s vertices and triangles.
    pub fn append(&mut self, other: &Mesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        self.uvs.extend_from_slice(&other.uvs);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
    }

    /// Checks the invariants the renderer relies on: every index in range,
    /// attribute arrays as long as the positions, finite coordinates.
    pub fn validate(&self) -> Result<(), InvalidMesh> {
        let invalid = |message: String| Err(InvalidMesh(message));
        let n = self.positions.len();
        if self.triangles.is_empty() {
            return invalid("no triangles".into());
        }
        if let Some(t) = self
            .triangles
            .iter()
            .find(|t| t.iter().any(|&i| i as usize >= n))
        {
            return invalid(format!("triangle {t:?} indexes past {n} vertices"));
        }
        if self.normals.len() != n || self.uvs.len() != n {
            return invalid(format!(
                "{n} vertices but {} normals and {} texture coordinates",
                self.normals.len(),
                self.uvs.len()
            ));
        }
        if self.positions.iter().any(|p| !p.is_finite()) {
            return invalid("a vertex position is not a finite number".into());
        }
        Ok(())
    }
}

/// A mesh that breaks an invariant the renderer relies on; the message
/// says which.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct InvalidMesh(pub String);

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> Mesh {
        Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(2.0, 2.0, 0.0),
                Vec3::new(0.0, 2.0, 0.0),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..Mesh::default()
        }
    }

    #[test]
    fn normals_point_out_of_counter_clockwise_faces() {
        let mut m = quad();
        m.compute_normals();
        assert!(m.normals.iter().all(|&n| n == Vec3::Z));
    }

    #[test]
    fn box_projection_spans_the_unit_square() {
        let mut m = quad();
        m.project_uvs(UvProjection::Box);
        assert_eq!(m.uvs, vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
        m.validate().unwrap();
    }

    #[test]
    fn validation_names_the_broken_invariant() {
        let mut m = quad();
        m.compute_normals();
        m.project_uvs(UvProjection::Sphere);
        m.triangles.push([0, 1, 9]);
        assert!(m.validate().unwrap_err().0.contains("past 4 vertices"));
    }

    #[test]
    fn normalising_centres_and_scales() {
        let mut m = quad();
        m.normalise_to_radius(1.0);
        assert!((m.bounding_radius() - 1.0).abs() < 1e-6);
        assert!(m.bounds().centre().length() < 1e-6);
    }
}
