//! Sequences of one 3D scene (pipeline.md §3.4): the same objects,
//! materials and splits rendered frame after frame while the camera orbits
//! its target and moves in, and the light dims and turns. Every frame is a
//! complete scene description, so its annotation is as exact as a single
//! render's.

use crate::recipe::{read_toml, RecipeError};
use matseg_extract::OutOfRange;
use matseg_render::environment::Light;
use matseg_render::{SceneDescription, Vec3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How a scene changes from its first frame to its last; each change is
/// spread evenly over the frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraPath {
    /// Frames in the sequence (at least 1).
    pub frames: u32,
    /// Degrees the camera turns about the vertical axis through its target.
    pub orbit_deg: f32,
    /// Degrees its elevation rises (negative: falls), kept within ±85°.
    pub rise_deg: f32,
    /// Its distance to the target on the last frame, as a share of the first.
    pub dolly: f32,
    /// The light's strength on the last frame (environment and lamps), as a
    /// share of the first.
    pub light_gain: f32,
    /// Degrees the environment turns about the vertical axis.
    pub environment_turn_deg: f32,
}

impl Default for CameraPath {
    fn default() -> Self {
        CameraPath {
            frames: 12,
            orbit_deg: 60.0,
            rise_deg: 10.0,
            dolly: 0.8,
            light_gain: 0.5,
            environment_turn_deg: 90.0,
        }
    }
}

impl CameraPath {
    /// The defaults with `frames` frames.
    pub fn with_frames(frames: u32) -> Self {
        CameraPath {
            frames,
            ..Self::default()
        }
    }

    /// Reads a path from TOML (any field may be left out) and checks it.
    pub fn from_toml_file(path: &Path) -> Result<Self, RecipeError> {
        let camera_path: Self = read_toml(path, "camera path")?;
        camera_path.validate().map_err(|e| RecipeError::Invalid {
            origin: path.display().to_string(),
            reason: e.0,
        })?;
        Ok(camera_path)
    }

    /// Checks the frame count and that every share is positive and finite.
    pub fn validate(&self) -> Result<(), OutOfRange> {
        if !(1..=100_000).contains(&self.frames) {
            return Err(OutOfRange(format!(
                "frames = {} must be in 1..100000",
                self.frames
            )));
        }
        for (name, v) in [("dolly", self.dolly), ("light_gain", self.light_gain)] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(OutOfRange(format!("{name} = {v} must be positive")));
            }
        }
        for (name, v) in [
            ("orbit_deg", self.orbit_deg),
            ("rise_deg", self.rise_deg),
            ("environment_turn_deg", self.environment_turn_deg),
        ] {
            if !v.is_finite() {
                return Err(OutOfRange(format!("{name} = {v} must be finite")));
            }
        }
        Ok(())
    }

    /// How far frame `frame` is along the path: 0 on the first, 1 on the
    /// last (0 throughout a one-frame path).
    pub fn progress(&self, frame: u32) -> f32 {
        if self.frames <= 1 {
            0.0
        } else {
            frame.min(self.frames - 1) as f32 / (self.frames - 1) as f32
        }
    }

    /// Frame `frame` of the sequence whose first frame is `scene`: the
    /// camera orbited, raised and moved in about its target, the light
    /// scaled and the environment turned by this frame's share of the path;
    /// the renderer's seed advanced by the frame, so noise changes from
    /// frame to frame as a camera's does.
    pub fn frame(&self, scene: &SceneDescription, frame: u32) -> SceneDescription {
        let t = self.progress(frame);
        let mut out = scene.clone();
        out.seed = scene.seed.wrapping_add(frame as u64);
        let camera = &mut out.camera;
        let offset = camera.position - camera.target;
        let distance = offset.length();
        let horizontal = (offset.x * offset.x + offset.y * offset.y).sqrt();
        let azimuth = offset.y.atan2(offset.x) + (self.orbit_deg * t).to_radians();
        let elevation = (offset.z.atan2(horizontal) + (self.rise_deg * t).to_radians())
            .clamp(-85f32.to_radians(), 85f32.to_radians());
        let distance = distance * (1.0 + (self.dolly - 1.0) * t);
        camera.position = camera.target
            + Vec3::new(
                elevation.cos() * azimuth.cos(),
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
            ) * distance;
        let gain = 1.0 + (self.light_gain - 1.0) * t;
        out.environment.strength *= gain;
        out.environment.rotation_deg += self.environment_turn_deg * t;
        for light in &mut out.lights {
            match light {
                Light::Point { intensity, .. } | Light::Spot { intensity, .. } => {
                    *intensity *= gain;
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene() -> SceneDescription {
        let mut scene: SceneDescription = serde_json::from_str(
            r#"{"width": 8, "height": 8, "spp": 1, "seed": 7,
                "camera": {"position": {"x": 4, "y": 0, "z": 0},
                           "target": {"x": 0, "y": 0, "z": 0}},
                "environment": {}, "materials": [], "objects": []}"#,
        )
        .unwrap();
        scene.lights = vec![Light::Point {
            position: Vec3::new(0.0, 0.0, 5.0),
            intensity: Vec3::ONE * 10.0,
        }];
        scene
    }

    #[test]
    fn the_first_frame_is_the_scene_and_the_last_has_gone_the_whole_path() {
        let scene = scene();
        let path = CameraPath {
            frames: 5,
            orbit_deg: 90.0,
            rise_deg: 0.0,
            dolly: 0.5,
            light_gain: 0.25,
            environment_turn_deg: 40.0,
        };
        let first = path.frame(&scene, 0);
        assert!((first.camera.position - scene.camera.position).length() < 1e-5);
        assert_eq!(first.environment, scene.environment);
        let last = path.frame(&scene, 4);
        // A quarter turn about z at half the distance: from +x to +y, 2 away.
        let p = last.camera.position;
        assert!((p - Vec3::new(0.0, 2.0, 0.0)).length() < 1e-5, "{p:?}");
        assert_eq!(last.seed, 11);
        assert!((last.environment.strength - 0.25 * scene.environment.strength).abs() < 1e-6);
        assert!((last.environment.rotation_deg - 40.0).abs() < 1e-6);
        let Light::Point { intensity, .. } = last.lights[0] else {
            panic!("a point light")
        };
        assert!((intensity.x - 2.5).abs() < 1e-5);
        // Halfway: half the turn, three quarters of the distance.
        let mid = path.frame(&scene, 2).camera.position;
        assert!((mid.length() - 3.0).abs() < 1e-5);
        assert!((mid.y.atan2(mid.x).to_degrees() - 45.0).abs() < 1e-3);
        assert_eq!(path.frame(&scene, 2).camera.target, Vec3::ZERO);
    }

    #[test]
    fn the_elevation_stays_off_the_pole_and_bad_paths_are_refused() {
        let scene = scene();
        let path = CameraPath {
            frames: 2,
            rise_deg: 200.0,
            ..CameraPath::default()
        };
        let top = path.frame(&scene, 1).camera.position;
        let elevation = top.z.atan2((top.x * top.x + top.y * top.y).sqrt());
        assert!((elevation.to_degrees() - 85.0).abs() < 1e-3);
        assert_eq!(CameraPath::with_frames(1).progress(0), 0.0);
        let zero = CameraPath {
            frames: 0,
            ..CameraPath::default()
        };
        assert!(zero.validate().unwrap_err().0.contains("frames = 0"));
        let dark = CameraPath {
            light_gain: 0.0,
            ..CameraPath::default()
        };
        assert!(dark.validate().unwrap_err().0.contains("light_gain"));
    }
}
