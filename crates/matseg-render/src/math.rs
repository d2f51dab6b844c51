//! Small 3D maths: vectors, rays, boxes, orthonormal frames and affine
//! transforms. Single precision, as in most production path tracers.

use serde::{Deserialize, Serialize};
use std::ops::{Add, AddAssign, Div, Index, Mul, MulAssign, Neg, Sub};

/// A 3-vector: a point, a direction or an RGB triple.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vec3 {
    /// First component.
    pub x: f32,
    /// Second component.
    pub y: f32,
    /// Third component (up in world space).
    pub z: f32,
}

impl Vec3 {
    /// All zeros.
    pub const ZERO: Vec3 = Vec3::new(0.0, 0.0, 0.0);
    /// All ones.
    pub const ONE: Vec3 = Vec3::new(1.0, 1.0, 1.0);
    /// The world's up direction.
    pub const Z: Vec3 = Vec3::new(0.0, 0.0, 1.0);

    /// A vector from its components.
    #[inline]
    pub const fn new(x: f32, y: f32, z: f32) -> Self {
        Vec3 { x, y, z }
    }

    /// The same value in every component.
    #[inline]
    pub const fn splat(v: f32) -> Self {
        Vec3::new(v, v, v)
    }

    /// Dot product.
    #[inline]
    pub fn dot(self, o: Vec3) -> f32 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Cross product.
    #[inline]
    pub fn cross(self, o: Vec3) -> Vec3 {
        Vec3::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }

    /// Euclidean length.
    #[inline]
    pub fn length(self) -> f32 {
        self.dot(self).sqrt()
    }

    /// The unit vector in the same direction (zero stays zero).
    #[inline]
    pub fn normalised(self) -> Vec3 {
        let l = self.length();
        if l > 0.0 {
            self * (1.0 / l)
        } else {
            self
        }
    }

    /// Component-wise product.
    #[inline]
    pub fn mul_elem(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }

    /// Component-wise minimum.
    #[inline]
    pub fn min(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x.min(o.x), self.y.min(o.y), self.z.min(o.z))
    }

    /// Component-wise maximum.
    #[inline]
    pub fn max(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x.max(o.x), self.y.max(o.y), self.z.max(o.z))
    }

    /// The largest component.
    #[inline]
    pub fn max_elem(self) -> f32 {
        self.x.max(self.y).max(self.z)
    }

    /// Rec. 709 luminance of a linear RGB triple.
    #[inline]
    pub fn luminance(self) -> f32 {
        0.2126 * self.x + 0.7152 * self.y + 0.0722 * self.z
    }

    /// Linear interpolation: `self` at 0, `o` at 1.
    #[inline]
    pub fn lerp(self, o: Vec3, t: f32) -> Vec3 {
        self + (o - self) * t
    }

    /// Whether every component is finite.
    #[inline]
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }

    /// The components as an array.
    #[inline]
    pub fn to_array(self) -> [f32; 3] {
        [self.x, self.y, self.z]
    }
}

impl From<[f32; 3]> for Vec3 {
    fn from([x, y, z]: [f32; 3]) -> Self {
        Vec3::new(x, y, z)
    }
}

impl Index<usize> for Vec3 {
    type Output = f32;
    #[inline]
    fn index(&self, i: usize) -> &f32 {
        match i {
            0 => &self.x,
            1 => &self.y,
            _ => &self.z,
        }
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    #[inline]
    fn add(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl AddAssign for Vec3 {
    #[inline]
    fn add_assign(&mut self, o: Vec3) {
        *self = *self + o;
    }
}

impl Sub for Vec3 {
    type Output = Vec3;
    #[inline]
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl Neg for Vec3 {
    type Output = Vec3;
    #[inline]
    fn neg(self) -> Vec3 {
        Vec3::new(-self.x, -self.y, -self.z)
    }
}

impl Mul<f32> for Vec3 {
    type Output = Vec3;
    #[inline]
    fn mul(self, s: f32) -> Vec3 {
        Vec3::new(self.x * s, self.y * s, self.z * s)
    }
}

impl MulAssign<f32> for Vec3 {
    #[inline]
    fn mul_assign(&mut self, s: f32) {
        *self = *self * s;
    }
}

impl Div<f32> for Vec3 {
    type Output = Vec3;
    #[inline]
    fn div(self, s: f32) -> Vec3 {
        self * (1.0 / s)
    }
}

/// A ray: origin and (not necessarily unit) direction.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Where it starts.
    pub origin: Vec3,
    /// Where it goes.
    pub dir: Vec3,
}

impl Ray {
    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// An axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (grows from nothing).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The box grown to hold `p`.
    #[inline]
    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The box holding both.
    #[inline]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// Surface area (0 for the empty box).
    #[inline]
    pub fn area(self) -> f32 {
        let d = self.max - self.min;
        if d.x < 0.0 || d.y < 0.0 || d.z < 0.0 {
            return 0.0;
        }
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    /// The centre.
    #[inline]
    pub fn centre(self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// The distance along the ray where it enters the box, if it does so
    /// within `(0, t_max)`; `inv_dir` is `1 / ray.dir` per component.
    #[inline]
    pub fn hit(&self, origin: Vec3, inv_dir: Vec3, t_max: f32) -> Option<f32> {
        // Plain comparisons rather than f32::min/max, whose NaN rules cost
        // extra instructions in the hottest test of the renderer (a NaN from
        // 0 * inf on a slab plane just picks the other operand).
        #[inline(always)]
        fn lo(a: f32, b: f32) -> f32 {
            if a < b {
                a
            } else {
                b
            }
        }
        #[inline(always)]
        fn hi(a: f32, b: f32) -> f32 {
            if a > b {
                a
            } else {
                b
            }
        }
        let t0 = (self.min - origin).mul_elem(inv_dir);
        let t1 = (self.max - origin).mul_elem(inv_dir);
        let near = hi(hi(lo(t0.x, t1.x), lo(t0.y, t1.y)), hi(lo(t0.z, t1.z), 0.0));
        let far = lo(
            lo(hi(t0.x, t1.x), hi(t0.y, t1.y)),
            lo(hi(t0.z, t1.z), t_max),
        );
        (near <= far).then_some(near)
    }
}

/// An orthonormal frame around a unit normal, for moving directions between
/// world space and a local space where the normal is +z.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Local x axis.
    pub s: Vec3,
    /// Local y axis.
    pub t: Vec3,
    /// Local z axis (the normal).
    pub n: Vec3,
}

impl Frame {
    /// A frame around `n` (unit length), with tangents chosen without
    /// branches on the sign of `n.z` (Duff et al., "Building an orthonormal
    /// basis, revisited", 2017).
    pub fn from_normal(n: Vec3) -> Frame {
        let sign = 1f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        Frame {
            s: Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
            t: Vec3::new(b, sign + n.y * n.y * a, -n.y),
            n,
        }
    }

    /// A frame around `n` whose first axis follows `tangent` as closely as
    /// possible (Gram-Schmidt); falls back to [`Frame::from_normal`] when
    /// the tangent is parallel to the normal.
    pub fn from_normal_tangent(n: Vec3, tangent: Vec3) -> Frame {
        let s = tangent - n * n.dot(tangent);
        let len = s.length();
        if len < 1e-6 || !len.is_finite() {
            return Frame::from_normal(n);
        }
        let s = s / len;
        Frame {
            s,
            t: n.cross(s),
            n,
        }
    }

    /// World to local.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// Local to world.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// An affine transform: `p -> linear * p + translation`, with the linear
/// part as three rows.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Rows of the 3x3 linear part.
    pub linear: [Vec3; 3],
    /// The translation.
    pub translation: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Transform::IDENTITY
    }
}

impl Transform {
    /// Leaves everything where it is.
    pub const IDENTITY: Transform = Transform {
        linear: [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ],
        translation: Vec3::ZERO,
    };

    /// Uniform scale, then rotation by Euler angles in degrees (about x,
    /// then y, then z), then translation.
    pub fn from_parts(scale: f32, rotation_deg: Vec3, translation: Vec3) -> Transform {
        let (sx, cx) = rotation_deg.x.to_radians().sin_cos();
        let (sy, cy) = rotation_deg.y.to_radians().sin_cos();
        let (sz, cz) = rotation_deg.z.to_radians().sin_cos();
        // R = Rz * Ry * Rx.
        let r = [
            Vec3::new(cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx),
            Vec3::new(sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx),
            Vec3::new(-sy, cy * sx, cy * cx),
        ];
        Transform {
            linear: r.map(|row| row * scale),
            translation,
        }
    }

    /// A transformed point.
    #[inline]
    pub fn point(&self, p: Vec3) -> Vec3 {
        self.vector(p) + self.translation
    }

    /// A transformed direction (no translation).
    #[inline]
    pub fn vector(&self, v: Vec3) -> Vec3 {
        Vec3::new(
            self.linear[0].dot(v),
            self.linear[1].dot(v),
            self.linear[2].dot(v),
        )
    }

    /// A transformed surface normal (by the inverse transpose; unit length).
    pub fn normal(&self, n: Vec3) -> Vec3 {
        // The inverse transpose is the cofactor matrix over the determinant;
        // the determinant's magnitude does not matter after normalising, its
        // sign does.
        let [a, b, c] = self.linear;
        let cof = [b.cross(c), c.cross(a), a.cross(b)];
        let det = a.dot(cof[0]);
        let m = Vec3::new(cof[0].x, cof[1].x, cof[2].x) * n.x
            + Vec3::new(cof[0].y, cof[1].y, cof[2].y) * n.y
            + Vec3::new(cof[0].z, cof[1].z, cof[2].z) * n.z;
        (m * det.signum()).normalised()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn frames_are_orthonormal_and_round_trip() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::new(0.3, -0.5, 0.81).normalised(),
            Vec3::new(1.0, 0.0, 0.0),
        ] {
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-5 && (f.t.length() - 1.0).abs() < 1e-5);
            assert!(
                f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5
            );
            assert!(close(f.s.cross(f.t), n), "right-handed around {n:?}");
            let v = Vec3::new(0.2, 0.7, -0.4);
            assert!(close(f.to_world(f.to_local(v)), v));
            assert!(close(f.to_local(n), Vec3::Z));
        }
    }

    #[test]
    fn transforms_rotate_scale_and_keep_normals_perpendicular() {
        let t = Transform::from_parts(2.0, Vec3::new(0.0, 0.0, 90.0), Vec3::new(1.0, 2.0, 3.0));
        assert!(close(
            t.point(Vec3::new(1.0, 0.0, 0.0)),
            Vec3::new(1.0, 4.0, 3.0)
        ));
        let t = Transform::from_parts(1.5, Vec3::new(30.0, -20.0, 75.0), Vec3::ZERO);
        let (a, b) = (Vec3::new(1.0, 0.2, 0.0), Vec3::new(0.0, 0.3, 1.0));
        let n = a.cross(b).normalised();
        let tn = t.normal(n);
        assert!(tn.dot(t.vector(a)).abs() < 1e-4 && tn.dot(t.vector(b)).abs() < 1e-4);
        assert!(
            tn.dot(t.vector(a).cross(t.vector(b))) > 0.0,
            "orientation kept"
        );
    }

    #[test]
    fn boxes_are_hit_where_the_slabs_overlap() {
        let b = Aabb {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        };
        let o = Vec3::new(-3.0, 0.0, 0.0);
        let d = Vec3::new(1.0, 0.0, 0.0);
        let inv = Vec3::new(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
        assert_eq!(b.hit(o, inv, f32::INFINITY), Some(2.0));
        assert_eq!(b.hit(o, inv, 1.5), None);
        let o2 = Vec3::new(-3.0, 2.0, 0.0);
        assert_eq!(b.hit(o2, inv, f32::INFINITY), None);
        assert_eq!(b.area(), 24.0);
    }
}
