//! One material layer of a 2D scene (SPEC 2): a texture (tiled or stretched,
//! rotated, mirrored, hue-shifted) or a flat colour, with optional shading.

use crate::recipe::CompositionRecipe;
use matseg_extract::random_placement;
use matseg_image::color::rotate_hue;
use matseg_image::{
    gaussian_blur, Channel, LibraryError, PhotoLibrary, Placement, Plane, Pyramid, RgbF32,
};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// How a texture covers the scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case")]
pub enum Fill {
    /// Repeated: shrunk by `shrink` (1 = native size) to a `tile_w x tile_h`
    /// tile, then repeated from the phase `(offset_x, offset_y)`.
    Tile {
        /// Shrink ratio applied before tiling.
        shrink: f64,
        /// Tile width after shrinking.
        tile_w: u32,
        /// Tile height after shrinking.
        tile_h: u32,
        /// Horizontal phase of the repetition.
        offset_x: u32,
        /// Vertical phase of the repetition.
        offset_y: u32,
    },
    /// Scaled (aspect ratio kept) to cover the scene and cropped.
    Stretch {
        /// Resize and crop.
        placement: Placement,
    },
}

/// Where a material's colour comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum MaterialSource {
    /// A texture from the texture library.
    Texture {
        /// Index in the texture library.
        texture: usize,
        /// Rotated by 90 degrees (counter-clockwise) first.
        rot90: bool,
        /// Then mirrored left-right.
        flip_x: bool,
        /// Then mirrored top-bottom.
        flip_y: bool,
        /// How it covers the scene.
        fill: Fill,
        /// Hue rotation in degrees, if any.
        hue_shift_degrees: Option<f32>,
    },
    /// One colour everywhere.
    FlatColour {
        /// The colour.
        rgb: [u8; 3],
    },
}

/// Shadow-like shading: `layer *= (1 - strength) + strength * shade`, where
/// `shade` is a blurred photo channel divided by its maximum.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShadingRecord {
    /// Index of the photo in the photo library.
    pub photo: usize,
    /// How it was resized and cropped.
    pub placement: Placement,
    /// Channel used.
    pub channel: Channel,
    /// Gaussian kernel size.
    pub kernel: usize,
    /// Strength in [0, 1].
    pub strength: f32,
}

/// How one material layer was drawn.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialRecord {
    /// Its colour source.
    pub source: MaterialSource,
    /// Its shading, if any.
    pub shading: Option<ShadingRecord>,
}

/// Draws one material and adds it, weighted by `weight`, into `acc`. Hue
/// shift, shading and blending touch only the pixels where `weight > 0`.
pub fn add_material<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &CompositionRecipe,
    photos: &PhotoLibrary,
    textures: &PhotoLibrary,
    weight: &Plane,
    acc: &mut RgbF32,
) -> Result<MaterialRecord, LibraryError> {
    let (w, h) = (weight.width, weight.height);
    let (layer, source) = if rng.random_bool(recipe.p_texture) {
        let (layer, source) = draw_texture(rng, recipe, textures, w, h)?;
        (Some(layer), source)
    } else {
        let rgb = [rng.random::<u8>(), rng.random::<u8>(), rng.random::<u8>()];
        (None, MaterialSource::FlatColour { rgb })
    };
    let shading = if rng.random_bool(recipe.p_shading) {
        Some(draw_shading(rng, recipe, photos, w, h)?)
    } else {
        None
    };

    let (flat, hue) = match &source {
        MaterialSource::FlatColour { rgb } => ([rgb[0] as f32, rgb[1] as f32, rgb[2] as f32], None),
        MaterialSource::Texture {
            hue_shift_degrees, ..
        } => ([0.0; 3], *hue_shift_degrees),
    };
    for (i, &wk) in weight.data.iter().enumerate() {
        if wk <= 0.0 {
            continue;
        }
        let mut px = layer.as_ref().map_or(flat, |l| l.data[i]);
        if let Some(deg) = hue {
            px = rotate_hue(px, deg);
        }
        let factor = shading.as_ref().map_or(1.0, |(shade, s)| {
            (1.0 - s.strength) + s.strength * shade.data[i]
        });
        for (a, p) in acc.data[i].iter_mut().zip(px) {
            *a += p * factor * wk;
        }
    }
    Ok(MaterialRecord {
        source,
        shading: shading.map(|(_, record)| record),
    })
}

fn draw_texture<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &CompositionRecipe,
    textures: &PhotoLibrary,
    w: usize,
    h: usize,
) -> Result<(RgbF32, MaterialSource), LibraryError> {
    let texture = textures.pick(|n| rng.random_range(0..n))?;
    let rot90 = rng.random_bool(recipe.p_rot90);
    let flip_x = rng.random_bool(recipe.p_flip_x);
    let flip_y = rng.random_bool(recipe.p_flip_y);
    let transformed;
    let pyramid = if rot90 || flip_x || flip_y {
        let mut img = texture.pyramid.base().clone();
        if rot90 {
            img = image::imageops::rotate270(&img);
        }
        if flip_x {
            image::imageops::flip_horizontal_in_place(&mut img);
        }
        if flip_y {
            image::imageops::flip_vertical_in_place(&mut img);
        }
        transformed = Pyramid::new(img);
        &transformed
    } else {
        &texture.pyramid
    };

    let (tw, th) = (pyramid.width(), pyramid.height());
    let (layer, fill) = if rng.random_bool(recipe.p_tile) {
        let max_shrink = (tw.min(th) as f64 / recipe.min_tile_side).max(1.0);
        let shrink = if rng.random_bool(recipe.p_tile_shrink) {
            rng.random_range(1.0..=max_shrink)
        } else {
            1.0
        };
        let tile_w = ((tw as f64 / shrink).round() as u32).max(1);
        let tile_h = ((th as f64 / shrink).round() as u32).max(1);
        let tile = pyramid.resize_rgb(tile_w as usize, tile_h as usize);
        let offset_x = rng.random_range(0..tile_w);
        let offset_y = rng.random_range(0..tile_h);
        let mut data = Vec::with_capacity(w * h);
        for y in 0..h {
            let ty = (y + offset_y as usize) % tile_h as usize;
            let row = &tile.data[ty * tile_w as usize..(ty + 1) * tile_w as usize];
            data.extend((0..w).map(|x| row[(x + offset_x as usize) % tile_w as usize]));
        }
        let fill = Fill::Tile {
            shrink,
            tile_w,
            tile_h,
            offset_x,
            offset_y,
        };
        (
            RgbF32 {
                width: w,
                height: h,
                data,
            },
            fill,
        )
    } else {
        let scale = Placement::cover_scale(tw, th, w, h);
        let (rw, rh) = Placement::resized_size(tw, th, scale, w, h);
        let placement = Placement {
            resized_w: rw,
            resized_h: rh,
            x0: rng.random_range(0..=rw - w as u32),
            y0: rng.random_range(0..=rh - h as u32),
        };
        (
            pyramid.sample_rgb(&placement, w, h),
            Fill::Stretch { placement },
        )
    };

    let hue_shift_degrees = rng
        .random_bool(recipe.p_hue_shift)
        .then(|| rng.random_range(0.0..360.0f32));
    let source = MaterialSource::Texture {
        texture: texture.index,
        rot90,
        flip_x,
        flip_y,
        fill,
        hue_shift_degrees,
    };
    Ok((layer, source))
}

/// Draws the shading of one material: the blurred, max-normalised photo
/// channel, and its record (which holds the strength).
fn draw_shading<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &CompositionRecipe,
    photos: &PhotoLibrary,
    w: usize,
    h: usize,
) -> Result<(Plane, ShadingRecord), LibraryError> {
    let photo = photos.pick(|n| rng.random_range(0..n))?;
    let placement = random_placement(rng, &photo, w, h, recipe.p_shading_downscale, false);
    let channels = if rng.random_bool(recipe.p_shading_hsv) {
        Channel::HSV
    } else {
        Channel::RGB
    };
    let channel = channels[rng.random_range(0..3)];
    let mut shade = photo.pyramid.sample_channel(&placement, w, h, channel);
    let max = shade.max();
    if max > 0.0 {
        shade.scale(1.0 / max);
    }
    let kernel = recipe.shading_kernels[rng.random_range(0..recipe.shading_kernels.len())];
    let shade = gaussian_blur(&shade, kernel);
    let strength = if rng.random_bool(recipe.p_shading_full_strength) {
        1.0
    } else {
        rng.random::<f32>()
    };
    let record = ShadingRecord {
        photo: photo.index,
        placement,
        channel,
        kernel,
        strength,
    };
    Ok((shade, record))
}
