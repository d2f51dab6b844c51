//! The 3D recipe: every probability and range of pipeline.md §3 as a named
//! field with the paper's value as default, overridable from TOML.

use crate::recipe::{read_toml, RecipeError};
use matseg_extract::OutOfRange;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How 3D scenes are drawn.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Recipe3d {
    /// Image side in pixels (square images).
    pub size: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Longest light path, in bounces.
    pub max_bounces: u32,
    /// Denoise images (edge-aware; the annotation is never filtered).
    pub denoise: bool,
    /// Probability that the main object is one object ...
    pub p_single_object: f64,
    /// ... of bounding radius in this range.
    pub single_radius: [f32; 2],
    /// Probability that it is several objects merged (else: several smaller ones).
    pub p_merged_objects: f64,
    /// Number of merged objects (inclusive range).
    pub merged_count: [u32; 2],
    /// Bounding radius of each merged object.
    pub merged_radius: [f32; 2],
    /// Number of smaller objects (inclusive range).
    pub small_count: [u32; 2],
    /// Bounding radius of each smaller object.
    pub small_radius: [f32; 2],
    /// Objects of a group sit within this radius of the group's centre.
    pub group_spread: f32,
    /// Probability that an object is a mesh from the mesh folders (when
    /// there are any) rather than a procedural primitive.
    pub p_mesh: f64,
    /// Probability of K = U{materials_min..materials_max} materials on the
    /// main object (else 2).
    pub p_many_materials: f64,
    /// Fewest materials when many.
    pub materials_min: usize,
    /// Most materials when many (inclusive).
    pub materials_max: usize,
    /// Probability that a split is a hard step ...
    pub p_hard_split: f64,
    /// ... at a threshold in this range.
    pub hard_threshold: [f32; 2],
    /// Otherwise a soft ramp starting in this range ...
    pub soft_start: [f32; 2],
    /// ... with a width up to this fraction of its start.
    pub soft_width_max: f32,
    /// Probability that a split's photo channel is R, G or B (else H, S or V).
    pub p_rgb_channel: f64,
    /// Probability that a channel is divided by its maximum (else by 255).
    pub p_normalise_by_max: f64,
    /// log10 of a split photo's scale on the surface (UV units per photo).
    pub map_scale_log10: [f32; 2],
    /// Probability that a material is a PBR from the library (else random principled).
    pub p_pbr: f64,
    /// log10 of a PBR's texture scale (UV units per repeat).
    pub pbr_scale_log10: [f32; 2],
    /// Probability that a random principled material is a metal.
    pub p_metal: f64,
    /// Probability that a random principled material transmits light.
    pub p_transmissive: f64,
    /// Index of refraction of random principled materials.
    pub ior: [f32; 2],
    /// Probability that the HDRI's strength is 1 (else U(strength)).
    pub p_unit_strength: f64,
    /// HDRI strength range when not 1.
    pub strength: [f32; 2],
    /// Probability of a ground plane with a random PBR.
    pub p_ground: f64,
    /// Probability of distractor objects ...
    pub p_distractors: f64,
    /// ... this many (inclusive range) ...
    pub distractor_count: [u32; 2],
    /// ... of this bounding radius.
    pub distractor_radius: [f32; 2],
    /// Probability of extra point or spot lights ...
    pub p_extra_lights: f64,
    /// ... this many (inclusive range).
    pub extra_light_count: [u32; 2],
    /// Camera focal length in millimetres (36 mm sensor).
    pub focal_mm: f32,
    /// The camera is `distance_unit * (2 + 3U)` from the main object's
    /// bounding sphere (the paper: 20).
    pub distance_unit: f32,
    /// Elevation is `(1 - elevation_drop * U²) * 90°` (the paper: 1.1) ...
    pub elevation_drop: f32,
    /// ... but at least this many degrees above a ground plane.
    pub min_elevation_over_ground_deg: f32,
    /// Largest camera roll in degrees (either way).
    pub max_roll_deg: f32,
    /// The main object's PBR materials are all different files (while the
    /// library has enough); off by default, as in the paper, where two
    /// materials may be one PBR at two placements. Left out of the
    /// recipe's JSON when off, so datasets made before it resume.
    #[serde(skip_serializing_if = "is_false")]
    pub distinct_materials: bool,
}

fn is_false(b: &bool) -> bool {
    !*b
}

impl Default for Recipe3d {
    fn default() -> Self {
        Recipe3d {
            size: 512,
            spp: 16,
            max_bounces: 6,
            denoise: false,
            p_single_object: 0.5,
            single_radius: [40.0, 60.0],
            p_merged_objects: 0.5,
            merged_count: [1, 6],
            merged_radius: [20.0, 40.0],
            small_count: [1, 11],
            small_radius: [8.0, 25.0],
            group_spread: 45.0,
            p_mesh: 0.5,
            p_many_materials: 0.85,
            materials_min: 2,
            materials_max: 8,
            p_hard_split: 0.75,
            hard_threshold: [0.3, 0.7],
            soft_start: [0.4, 0.8],
            soft_width_max: 0.25,
            p_rgb_channel: 0.7,
            p_normalise_by_max: 0.5,
            map_scale_log10: [-1.0, 0.2],
            p_pbr: 0.8,
            pbr_scale_log10: [-2.0, 0.6],
            p_metal: 0.25,
            p_transmissive: 0.15,
            ior: [1.3, 1.8],
            p_unit_strength: 0.5,
            strength: [1.0, 2.5],
            p_ground: 0.25,
            p_distractors: 0.2,
            distractor_count: [1, 8],
            distractor_radius: [5.0, 25.0],
            p_extra_lights: 0.15,
            extra_light_count: [1, 3],
            focal_mm: 50.0,
            distance_unit: 20.0,
            elevation_drop: 1.1,
            min_elevation_over_ground_deg: 5.0,
            max_roll_deg: 10.0,
            distinct_materials: false,
        }
    }
}

impl Recipe3d {
    /// Reads a recipe from a TOML file (missing fields take their defaults,
    /// unknown ones are refused) and validates it; errors name the file.
    pub fn from_toml_file(path: &Path) -> Result<Self, RecipeError> {
        let recipe: Self = read_toml(path, "recipe")?;
        recipe.validate().map_err(|e| RecipeError::Invalid {
            origin: path.display().to_string(),
            reason: e.0,
        })?;
        Ok(recipe)
    }

    /// Checks probabilities, ranges and sizes; the message names the field.
    pub fn validate(&self) -> Result<(), OutOfRange> {
        let probabilities = [
            ("p_single_object", self.p_single_object),
            ("p_merged_objects", self.p_merged_objects),
            ("p_mesh", self.p_mesh),
            ("p_many_materials", self.p_many_materials),
            ("p_hard_split", self.p_hard_split),
            ("p_rgb_channel", self.p_rgb_channel),
            ("p_normalise_by_max", self.p_normalise_by_max),
            ("p_pbr", self.p_pbr),
            ("p_metal", self.p_metal),
            ("p_transmissive", self.p_transmissive),
            ("p_unit_strength", self.p_unit_strength),
            ("p_ground", self.p_ground),
            ("p_distractors", self.p_distractors),
            ("p_extra_lights", self.p_extra_lights),
        ];
        for (name, p) in probabilities {
            if !(0.0..=1.0).contains(&p) {
                return Err(OutOfRange(format!("{name} = {p} is not a probability")));
            }
        }
        let ranges = [
            ("single_radius", self.single_radius),
            ("merged_radius", self.merged_radius),
            ("small_radius", self.small_radius),
            ("distractor_radius", self.distractor_radius),
            ("hard_threshold", self.hard_threshold),
            ("soft_start", self.soft_start),
            ("map_scale_log10", self.map_scale_log10),
            ("pbr_scale_log10", self.pbr_scale_log10),
            ("ior", self.ior),
            ("strength", self.strength),
        ];
        for (name, [lo, hi]) in ranges {
            if lo > hi || !lo.is_finite() || !hi.is_finite() {
                return Err(OutOfRange(format!("{name} = [{lo}, {hi}] is not a range")));
            }
        }
        let counts = [
            ("merged_count", self.merged_count),
            ("small_count", self.small_count),
            ("distractor_count", self.distractor_count),
            ("extra_light_count", self.extra_light_count),
        ];
        for (name, [lo, hi]) in counts {
            if lo < 1 || lo > hi {
                return Err(OutOfRange(format!(
                    "{name} = [{lo}, {hi}] must be a range from 1 up"
                )));
            }
        }
        if self.materials_min < 2 || self.materials_min > self.materials_max {
            return Err(OutOfRange(format!(
                "materials_min..materials_max = {}..{} must be a range from 2 up",
                self.materials_min, self.materials_max
            )));
        }
        if self.size < 8 || self.size > 8192 || self.spp == 0 {
            return Err(OutOfRange(format!(
                "size {} must be in 8..8192 and spp at least 1",
                self.size
            )));
        }
        if self.single_radius[0] <= 0.0 || self.focal_mm <= 0.0 || self.distance_unit <= 0.0 {
            return Err(OutOfRange(
                "radii, focal_mm and distance_unit must be positive".into(),
            ));
        }
        let positive = |v: f32| v > 0.0;
        let not_negative = |v: f32| v >= 0.0;
        // A NaN fails both tests too.
        if !positive(self.group_spread)
            || !not_negative(self.soft_width_max)
            || !not_negative(self.max_roll_deg)
        {
            return Err(OutOfRange(format!(
                "group_spread ({}) must be positive, soft_width_max ({}) and max_roll_deg ({}) not negative",
                self.group_spread, self.soft_width_max, self.max_roll_deg
            )));
        }
        Ok(())
    }
}
