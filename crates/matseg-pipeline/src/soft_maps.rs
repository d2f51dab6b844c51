//! The soft maps of one photo (pipeline.md §1), drawn as for a scene and
//! written as images with their records, for inspection or reuse.

use crate::error::PipelineError;
use crate::files::{create_folder, write_file};
use matseg_data::sample_rng;
use matseg_extract::{combine_maps, draw_channel_map, CombinedMaps, MapRecord, MAX_MAPS};
use matseg_image::io::{encode_png_grey, encode_png_rgb, read_rgb};
use matseg_image::{PhotoLibrary, Plane};
use matseg_scene::{colourise, Recipe2d};
use rand::Rng;
use serde::Serialize;
use std::path::Path;

/// What to draw.
#[derive(Clone, Debug)]
pub struct PhotoMaps {
    /// Number of maps (1..=[`MAX_MAPS`]).
    pub maps: usize,
    /// Seed.
    pub seed: u64,
    /// A hard (one-hot) combination; otherwise drawn as for a scene.
    pub hard: bool,
    /// The maps' longer side at most, in pixels (at least 16).
    pub max_side: u32,
}

/// What was drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MapsSummary {
    /// The maps' size.
    pub width: usize,
    /// The maps' size.
    pub height: usize,
    /// Whether the combination was hard.
    pub hard: bool,
}

#[derive(Serialize)]
struct MapsFile {
    photo: String,
    width: usize,
    height: usize,
    hard: bool,
    max_occupancy: f64,
    maps: Vec<MapRecord>,
    combine: matseg_extract::CombineRecord,
}

impl PhotoMaps {
    /// Draws the maps of `photo` under `recipe` and writes into the folder
    /// `out` (made when missing; a staged output, matseg_image::outputs) each
    /// raw map and weight (`raw_KK.png`, `weight_KK.png`), the background,
    /// the colour preview and `maps.json` (the records that redraw them).
    pub fn write(
        &self,
        photo: &Path,
        recipe: &Recipe2d,
        out: &Path,
    ) -> Result<MapsSummary, PipelineError> {
        if !(1..=MAX_MAPS).contains(&self.maps) {
            return Err(PipelineError::Settings(format!(
                "-n must be between 1 and {MAX_MAPS}"
            )));
        }
        if self.max_side < 16 {
            return Err(PipelineError::Settings(
                "--max-side must be at least 16".into(),
            ));
        }
        let img = read_rgb(photo)?;
        let (pw, ph) = img.dimensions();
        let shrink = (self.max_side as f64 / pw.max(ph) as f64).min(1.0);
        let (w, h) = (
            ((pw as f64 * shrink).round() as usize).max(1),
            ((ph as f64 * shrink).round() as usize).max(1),
        );
        let (library, _) = PhotoLibrary::scan(&[photo.to_path_buf()], usize::MAX)
            .map_err(crate::sources::SourceError::from)?;
        let mut rng = sample_rng(self.seed, 0);
        let hard = self.hard || rng.random_bool(recipe.scene.p_hard);
        let max_occupancy = recipe.scene.draw_max_occupancy(&mut rng);
        let mut raw = Vec::with_capacity(self.maps);
        let mut records = Vec::with_capacity(self.maps);
        for _ in 0..self.maps {
            let (map, record) =
                draw_channel_map(&mut rng, &library, w, h, max_occupancy, hard, &recipe.maps)?;
            raw.push(map);
            records.push(record);
        }
        let raw_planes: Vec<_> = raw.iter().map(|m| m.to_plane()).collect();
        let CombinedMaps {
            weights,
            background,
            record: combine,
            ..
        } = combine_maps(&mut rng, raw, hard, &recipe.maps);
        let weights: Vec<Plane> = weights.iter().map(|w| w.to_plane()).collect();
        create_folder(out)?;
        let write = |name: String, bytes: Vec<u8>| write_file(&out.join(name), &bytes);
        let grey = |plane: &Plane| encode_png_grey(w as u32, h as u32, &plane.to_u8());
        for (k, (r, wgt)) in raw_planes.iter().zip(&weights).enumerate() {
            write(format!("raw_{k:02}.png"), grey(r))?;
            write(format!("weight_{k:02}.png"), grey(wgt))?;
        }
        write("background.png".into(), grey(&background))?;
        let slices: Vec<&[f32]> = weights.iter().map(|p| p.data.as_slice()).collect();
        write(
            "colour.png".into(),
            encode_png_rgb(&colourise(w, h, &slices)),
        )?;
        let file = MapsFile {
            photo: photo.display().to_string(),
            width: w,
            height: h,
            hard,
            max_occupancy,
            maps: records,
            combine,
        };
        write(
            "maps.json".into(),
            serde_json::to_vec_pretty(&file).expect("records serialise"),
        )?;
        Ok(MapsSummary {
            width: w,
            height: h,
            hard,
        })
    }
}
