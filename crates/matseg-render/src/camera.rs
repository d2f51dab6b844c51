//! A pinhole camera described like a real one: position, target, roll,
//! focal length and a 36 mm sensor across the image's longer side (the
//! convention of Blender's default camera).

use crate::math::{Frame, Ray, Vec3};
use serde::{Deserialize, Serialize};

/// Sensor size across the longer image side, in millimetres.
pub const SENSOR_MM: f32 = 36.0;

/// Where the camera is and what it sees.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Position of the pinhole.
    pub position: Vec3,
    /// The point at the image centre.
    pub target: Vec3,
    /// Rotation about the viewing axis, degrees (positive turns the camera
    /// counter-clockwise as seen from behind it, so the image's right edge
    /// rises).
    #[serde(default)]
    pub roll_deg: f32,
    /// Focal length in millimetres.
    #[serde(default = "default_focal")]
    pub focal_mm: f32,
}

fn default_focal() -> f32 {
    50.0
}

/// A camera prepared for an image size.
#[derive(Clone, Debug)]
pub struct CameraRays {
    origin: Vec3,
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    width: f32,
    height: f32,
    /// Half the image's extent on the plane at distance 1, per pixel.
    scale: f32,
}

impl Camera {
    /// Prepares rays for a `width x height` image. Fails when the camera
    /// sits on its target.
    pub fn rays(&self, width: u32, height: u32) -> Result<CameraRays, crate::SceneError> {
        let forward = (self.target - self.position).normalised();
        if forward == Vec3::ZERO || !forward.is_finite() {
            return Err(crate::SceneError::Invalid(
                "the camera's position and target coincide".into(),
            ));
        }
        // Up is world z, unless looking straight up or down.
        let world_up = if forward.cross(Vec3::Z).length() < 1e-4 {
            Vec3::new(0.0, 1.0, 0.0)
        } else {
            Vec3::Z
        };
        let frame = Frame::from_normal_tangent(forward, forward.cross(world_up));
        let (s, c) = self.roll_deg.to_radians().sin_cos();
        // frame.s points right, frame.t = forward x right points down.
        let right = frame.s * c - frame.t * s;
        let up = -(frame.t * c + frame.s * s);
        let longer = width.max(height) as f32;
        Ok(CameraRays {
            origin: self.position,
            right,
            up,
            forward,
            width: width as f32,
            height: height as f32,
            scale: SENSOR_MM / self.focal_mm.max(1e-3) / longer,
        })
    }
}

impl CameraRays {
    /// The ray through image position (x, y), in pixels from the top-left
    /// corner; unit direction.
    #[inline]
    pub fn ray(&self, x: f32, y: f32) -> Ray {
        let dx = (x - 0.5 * self.width) * self.scale;
        let dy = (0.5 * self.height - y) * self.scale;
        Ray {
            origin: self.origin,
            dir: (self.forward + self.right * dx + self.up * dy).normalised(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_centre_ray_hits_the_target_and_edges_follow_the_focal_length() {
        let cam = Camera {
            position: Vec3::new(0.0, -10.0, 0.0),
            target: Vec3::ZERO,
            roll_deg: 0.0,
            focal_mm: 36.0,
        };
        let rays = cam.rays(200, 100).unwrap();
        let centre = rays.ray(100.0, 50.0);
        assert!((centre.dir - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-6);
        // 36 mm sensor at 36 mm focal length: the right edge is at 45 degrees/2 ... tan = 0.5.
        let right = rays.ray(200.0, 50.0).dir;
        assert!(
            (right.x / right.y - 0.5).abs() < 1e-5 && right.x > 0.0,
            "{right:?}"
        );
        let top = rays.ray(100.0, 0.0).dir;
        assert!(
            (top.z / top.y - 0.25).abs() < 1e-5 && top.z > 0.0,
            "{top:?}"
        );
        let rolled = Camera {
            roll_deg: 90.0,
            ..cam.clone()
        }
        .rays(200, 100)
        .unwrap();
        let r = rolled.ray(200.0, 50.0).dir;
        assert!(
            r.z > 0.0 && r.x.abs() < 1e-5,
            "rolling 90 degrees turns right into up: {r:?}"
        );
        assert!(Camera {
            target: cam.position,
            ..cam
        }
        .rays(10, 10)
        .is_err());
    }
}
