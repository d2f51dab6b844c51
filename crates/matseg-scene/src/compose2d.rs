//! The 2D scene (pipeline.md §2): background photo and K material layers mixed by the
//! soft maps of pipeline.md §1; the weights are the exact annotation.

use crate::material::{draw_material, Layer, MaterialRecord};
use crate::recipe::{Recipe2d, SceneShape};
use matseg_extract::{make_soft_maps, random_placement, CombineRecord, MapRecord, SoftMapError};
use matseg_image::rgb::interleave_rounded;
use matseg_image::{CropWindow, LibraryError, PhotoLibrary, Plane, Pyramid, SparsePlane};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// The libraries a scene draws from.
#[derive(Clone, Copy, Debug)]
pub struct Sources<'a> {
    /// Natural photos: map sources, backgrounds, shading.
    pub photos: &'a PhotoLibrary,
    /// Uniform textures: material appearance.
    pub textures: &'a PhotoLibrary,
}

/// Where the background came from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BackgroundRecord {
    /// Index in the photo library.
    pub photo: usize,
    /// Resize and crop.
    pub placement: CropWindow,
}

/// Every drawn parameter of a 2D scene: with the sources, enough to redraw it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneRecord {
    /// Scene width.
    pub width: usize,
    /// Scene height.
    pub height: usize,
    /// Whether the annotation is one-hot.
    pub hard: bool,
    /// Largest fraction of the scene one map's top side may cover.
    pub max_occupancy: f64,
    /// One record per material map.
    pub maps: Vec<MapRecord>,
    /// How the maps were combined.
    pub combine: CombineRecord,
    /// The background.
    pub background: BackgroundRecord,
    /// One record per material layer.
    pub materials: Vec<MaterialRecord>,
}

/// A generated 2D scene with its exact soft annotation.
#[derive(Clone, Debug)]
pub struct Scene2d {
    /// The composed image.
    pub image: image::RgbImage,
    /// One weight map per material, in [0, 1], stored where it can be
    /// positive.
    pub weights: Vec<SparsePlane>,
    /// Background weight; with the material weights it sums to 1 per pixel.
    pub background: Plane,
    /// What was drawn.
    pub record: SceneRecord,
}

/// Failure to generate a scene.
#[derive(Debug, thiserror::Error)]
pub enum ComposeError {
    /// A source library failed.
    #[error(transparent)]
    Library(#[from] LibraryError),
    /// Maps could not be drawn.
    #[error(transparent)]
    Maps(#[from] SoftMapError),
}

/// Generates one 2D scene from `rng` (pipeline.md §1 and 2).
pub fn generate_2d<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &Recipe2d,
    sources: Sources<'_>,
) -> Result<Scene2d, ComposeError> {
    let SceneShape {
        width,
        height,
        materials: k,
        hard,
        max_occupancy,
    } = recipe.scene.draw(rng);
    let maps = make_soft_maps(
        rng,
        sources.photos,
        width,
        height,
        k,
        hard,
        max_occupancy,
        &recipe.maps,
    )?;

    let photo = sources.photos.pick(|n| rng.random_range(0..n))?;
    let placement = random_placement(
        rng,
        &photo,
        width,
        height,
        recipe.composition.p_background_downscale,
        true,
    );
    let drawn = (0..k)
        .map(|_| {
            draw_material(
                rng,
                &recipe.composition,
                sources.photos,
                sources.textures,
                width,
                height,
            )
        })
        .collect::<Result<Vec<_>, _>>()?;
    let weights = maps.combined;
    let mut layers: Vec<Layer> = drawn
        .iter()
        .zip(&weights.weights)
        .zip(&weights.coverage)
        .filter_map(|((material, weight), coverage)| material.layer(weight, coverage))
        .collect();
    let background = (&photo.pyramid, &placement);
    let image = compose_rows(width, height, background, &weights.background, &mut layers);
    drop(layers);
    let materials = drawn.into_iter().map(|m| m.into_record()).collect();
    let record = SceneRecord {
        width,
        height,
        hard,
        max_occupancy,
        maps: maps.maps,
        combine: weights.record,
        background: BackgroundRecord {
            photo: photo.index,
            placement,
        },
        materials,
    };
    Ok(Scene2d {
        image,
        weights: weights.weights,
        background: weights.background,
        record,
    })
}

/// The scene image, one row at a time so that each stays in cache: the
/// background photo's window (`placement` of the pyramid, resampled row by
/// row) times its weight `wb`, plus every layer.
fn compose_rows(
    w: usize,
    h: usize,
    (background, placement): (&Pyramid, &CropWindow),
    wb: &Plane,
    layers: &mut [Layer],
) -> image::RgbImage {
    // Rows are appended as they are made (zeroing the whole image first
    // cost a pass over memory out of cache).
    let mut raw = Vec::with_capacity(w * h * 3);
    let mut row = vec![0u8; w * 3];
    let mut acc = [vec![0f32; w], vec![0f32; w], vec![0f32; w]];
    background.sample_rows(placement, w, h, |y, pixels| {
        let weights = &wb.data[y * w..(y + 1) * w];
        for (a, pixels) in acc.iter_mut().zip(pixels) {
            weigh_row(a, pixels, weights);
        }
        for layer in layers.iter_mut() {
            layer.add_row(y, &mut acc);
        }
        let [r, g, b] = &acc;
        interleave_rounded([r, g, b], &mut row);
        raw.extend_from_slice(&row);
    });
    image::RgbImage::from_raw(w as u32, h as u32, raw)
        .expect("buffer length matches the image size")
}

/// `acc = pixels * weights`, element-wise, pixels as floats; also compiled
/// for AVX2, picked at run time.
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn weigh_row(acc: &mut [f32], pixels: &[u8], weights: &[f32]) {
    for ((a, &v), &wt) in acc.iter_mut().zip(pixels).zip(weights) {
        *a = v as f32 * wt;
    }
}

/// A source file a scene used, for sidecars and licence audits.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct SourceRef {
    /// What it was used for: `map`, `background`, `texture` or `shading`.
    pub role: String,
    /// Path relative to its source folder.
    pub file: String,
    /// Its licence.
    pub licence: String,
}

impl SceneRecord {
    /// Every source file the scene used, in drawing order.
    pub fn source_refs(&self, sources: Sources<'_>) -> Vec<SourceRef> {
        let photo = |role: &str, i: usize| {
            let e = &sources.photos.entries()[i];
            SourceRef {
                role: role.into(),
                file: e.name.clone(),
                licence: e.licence.clone(),
            }
        };
        let mut refs: Vec<SourceRef> = self.maps.iter().map(|m| photo("map", m.photo)).collect();
        refs.push(photo("background", self.background.photo));
        for m in &self.materials {
            if let crate::material::MaterialSource::Texture { texture, .. } = &m.source {
                let e = &sources.textures.entries()[*texture];
                refs.push(SourceRef {
                    role: "texture".into(),
                    file: e.name.clone(),
                    licence: e.licence.clone(),
                });
            }
            if let Some(s) = &m.shading {
                refs.push(photo("shading", s.photo));
            }
        }
        refs
    }
}
