//! One material layer of a 2D scene (SPEC 2): a texture (tiled or stretched,
//! rotated, mirrored, hue-shifted) or a flat colour, with optional shading.

use crate::recipe::CompositionRecipe;
use matseg_extract::random_channel_placement;
use matseg_image::rgb::rotate_hue_planes;
use matseg_image::{
    level_values, Channel, ChannelRows, Coverage, CoveredBlur, LevelTable, LibraryError, Mirrors,
    Photo, PhotoLibrary, Placement, Pyramid, SparsePlane, WindowRows,
};
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::sync::Arc;

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

/// A material drawn for a scene, not yet blended: its record, the texture
/// photo it reads and its shading.
pub(crate) struct DrawnMaterial {
    record: MaterialRecord,
    texture: Option<Arc<Photo>>,
    shading: Option<Shading>,
}

/// Draws one material of a `w x h` scene (SPEC 2): a texture or a flat
/// colour, and its shading; its pixels are made as it is blended.
pub(crate) fn draw_material<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &CompositionRecipe,
    photos: &PhotoLibrary,
    textures: &PhotoLibrary,
    w: usize,
    h: usize,
) -> Result<DrawnMaterial, LibraryError> {
    let (texture, source) = if rng.random_bool(recipe.p_texture) {
        let (texture, source) = draw_texture(rng, recipe, textures, w, h)?;
        (Some(texture), source)
    } else {
        let rgb = [rng.random::<u8>(), rng.random::<u8>(), rng.random::<u8>()];
        (None, MaterialSource::FlatColour { rgb })
    };
    let shading = if rng.random_bool(recipe.p_shading) {
        Some(draw_shading(rng, recipe, photos, w, h)?)
    } else {
        None
    };
    let record = MaterialRecord {
        source,
        shading: shading.as_ref().map(|s| s.record.clone()),
    };
    Ok(DrawnMaterial {
        record,
        texture,
        shading,
    })
}

impl DrawnMaterial {
    /// What was drawn.
    pub(crate) fn into_record(self) -> MaterialRecord {
        self.record
    }

    /// The layer that blends this material by `weight`, whose positive
    /// blocks `coverage` holds; `None` when the weight is zero everywhere.
    pub(crate) fn layer<'a>(
        &'a self,
        weight: &'a SparsePlane,
        coverage: &'a Coverage,
    ) -> Option<Layer<'a>> {
        // Pixels where the weight is 0 add nothing, so the shading blur and
        // the blending skip every block without one.
        if coverage.is_empty() {
            return None;
        }
        let (w, h) = (weight.width(), weight.height());
        Some(Layer {
            weight,
            coverage,
            colour: Colour::new(&self.record.source, self.texture.as_deref(), w, h),
            shading: self.shading.as_ref().map(|s| {
                (
                    Shade::new(s, w, h),
                    CoveredBlur::new(w, h, s.record.kernel, coverage),
                )
            }),
            rgb: [vec![0f32; w], vec![0f32; w], vec![0f32; w]],
            factor: vec![0f32; w],
        })
    }
}

/// One material's blending, row by row: its weight, where it is positive,
/// its colour, its shading with the blur that streams it, and row buffers.
pub(crate) struct Layer<'a> {
    weight: &'a SparsePlane,
    coverage: &'a Coverage,
    colour: Colour<'a>,
    shading: Option<(Shade<'a>, CoveredBlur<'a>)>,
    rgb: [Vec<f32>; 3],
    factor: Vec<f32>,
}

impl Layer<'_> {
    /// Adds row `y` of the layer into `acc` (row `y` of the scene, one
    /// slice per channel) on its covered blocks: colour times weight, times
    /// `(1 - strength) + strength * shade` when shaded. Rows come in
    /// increasing order.
    pub(crate) fn add_row(&mut self, y: usize, acc: &mut [Vec<f32>; 3]) {
        let shade = match &mut self.shading {
            Some((shade, blur)) => {
                let strength = shade.strength;
                match blur.row(y, |y, x0, run| shade.run(y, x0, run)) {
                    Some(row) => Some((row, strength)),
                    None => return,
                }
            }
            // An uncovered row has no runs.
            None => None,
        };
        let mut weights = self.weight.pieces(y);
        for (x0, x1) in self.coverage.runs(y) {
            let weight = weights.take(x0, x1);
            let factor = match shade {
                Some((shade, s)) => {
                    let factor = &mut self.factor[..x1 - x0];
                    shade_weights(factor, weight, &shade[x0..x1], s);
                    factor
                }
                None => weight,
            };
            let rgb = self.rgb.each_mut().map(|c| &mut c[..x1 - x0]);
            self.colour.fill_row(y, x0, rgb);
            let [r, g, b] = acc;
            let target = [&mut r[x0..x1], &mut g[x0..x1], &mut b[x0..x1]];
            add_weighted(target, &self.rgb, factor);
        }
    }
}

/// `factor = weight * ((1 - strength) + strength * shade)`, element-wise;
/// also compiled for AVX2, picked at run time (same arithmetic, same results).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn shade_weights(factor: &mut [f32], weight: &[f32], shade: &[f32], strength: f32) {
    for ((f, &wt), &v) in factor.iter_mut().zip(weight).zip(shade) {
        *f = wt * ((1.0 - strength) + strength * v);
    }
}

/// `acc[c] += colour[c] * factor` for each channel `c` over the length of
/// `factor`; also compiled for AVX2, picked at run time.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn add_weighted(acc: [&mut [f32]; 3], colour: &[Vec<f32>; 3], factor: &[f32]) {
    for (plane, values) in acc.into_iter().zip(colour) {
        for ((a, &v), &f) in plane.iter_mut().zip(values).zip(factor) {
            *a += v * f;
        }
    }
}

/// A texture's pixels before mirroring: the photo's cached quarter-turned
/// copy when it is drawn turned, else the photo itself.
fn drawn_pixels(texture: &Photo, rot90: bool) -> &Pyramid {
    if rot90 {
        texture.quarter_turned()
    } else {
        &texture.pyramid
    }
}

/// Draws a texture's placement (SPEC 2); the pixels are rendered later, only
/// where the material is visible (see [`Colour`]).
fn draw_texture<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &CompositionRecipe,
    textures: &PhotoLibrary,
    w: usize,
    h: usize,
) -> Result<(Arc<Photo>, MaterialSource), LibraryError> {
    let texture = textures.pick(|n| rng.random_range(0..n))?;
    let rot90 = rng.random_bool(recipe.p_rot90);
    let flip_x = rng.random_bool(recipe.p_flip_x);
    let flip_y = rng.random_bool(recipe.p_flip_y);
    let drawn = drawn_pixels(&texture, rot90);
    let (tw, th) = (drawn.width(), drawn.height());
    let fill = if rng.random_bool(recipe.p_tile) {
        let max_shrink = (tw.min(th) as f64 / recipe.min_tile_side).max(1.0);
        let shrink = if rng.random_bool(recipe.p_tile_shrink) {
            rng.random_range(1.0..=max_shrink)
        } else {
            1.0
        };
        let tile_w = ((tw as f64 / shrink).round() as u32).max(1);
        let tile_h = ((th as f64 / shrink).round() as u32).max(1);
        Fill::Tile {
            shrink,
            tile_w,
            tile_h,
            offset_x: rng.random_range(0..tile_w),
            offset_y: rng.random_range(0..tile_h),
        }
    } else {
        let scale = Placement::cover_scale(tw, th, w, h);
        let (rw, rh) = Placement::resized_size(tw, th, scale, w, h);
        Fill::Stretch {
            placement: Placement {
                resized_w: rw,
                resized_h: rh,
                x0: rng.random_range(0..=rw - w as u32),
                y0: rng.random_range(0..=rh - h as u32),
            },
        }
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
    Ok((texture, source))
}

/// A material's colour before shading, made row run by row run; its hue
/// turned by `hue_shift_degrees` if any.
enum Colour<'a> {
    /// One colour everywhere.
    Flat([f32; 3]),
    /// A tile: an 8-bit image of the texture as drawn (turned if it is,
    /// resized), read mirrored by `mirrors` and repeated: scene pixel `(x,
    /// y)` shows pixel `((x + phase_x) mod width, (y + phase_y) mod height)`
    /// of the mirrored image. A tile at the texture's own size is read from
    /// its photo, not copied.
    Tiled {
        planes: [Cow<'a, [u8]>; 3],
        width: usize,
        height: usize,
        mirrors: Mirrors,
        phase_x: usize,
        phase_y: usize,
        hue_shift_degrees: Option<f32>,
    },
    /// A stretched texture: a scene-sized window of it, made only on the
    /// runs blended (a material is visible on a few blocks of the scene)
    /// and read mirrored: scene pixel `(x, y)` shows the window's pixel
    /// `mirrors.source(x, y)`. `levels` is scratch.
    Stretched {
        rows: WindowRows<'a>,
        width: usize,
        height: usize,
        mirrors: Mirrors,
        hue_shift_degrees: Option<f32>,
        levels: Vec<u8>,
    },
}

impl<'a> Colour<'a> {
    /// The colour of a material of a `w x h` scene from its record;
    /// `texture` is the texture's photo for a texture.
    fn new(source: &MaterialSource, texture: Option<&'a Photo>, w: usize, h: usize) -> Self {
        let (fill, rot90, flip_x, flip_y, hue_shift_degrees) = match *source {
            MaterialSource::FlatColour { rgb } => return Colour::Flat(rgb.map(f32::from)),
            MaterialSource::Texture {
                ref fill,
                rot90,
                flip_x,
                flip_y,
                hue_shift_degrees,
                ..
            } => (fill, rot90, flip_x, flip_y, hue_shift_degrees),
        };
        let texture = texture.expect("a texture is drawn with its photo");
        // Mirrors are applied when reading rows.
        let pyramid = drawn_pixels(texture, rot90);
        let mirrors = Mirrors { flip_x, flip_y };
        let (planes, width, height, phase_x, phase_y) = match *fill {
            Fill::Stretch { placement } => {
                // The texture is mirrored before it is resized and cropped:
                // the crop of the mirrored image is the mirrored crop of the
                // unmirrored one at the mirrored corner.
                let (rw, rh) = (placement.resized_w as usize, placement.resized_h as usize);
                let (x0, y0) = (placement.x0 as usize, placement.y0 as usize);
                let window = Placement {
                    x0: if flip_x { rw - x0 - w } else { x0 } as u32,
                    y0: if flip_y { rh - y0 - h } else { y0 } as u32,
                    ..placement
                };
                return Colour::Stretched {
                    rows: WindowRows::new(pyramid, &window, w, h),
                    width: w,
                    height: h,
                    mirrors,
                    hue_shift_degrees,
                    levels: vec![0; w],
                };
            }
            Fill::Tile {
                tile_w,
                tile_h,
                offset_x,
                offset_y,
                ..
            } => {
                let (tw, th) = (tile_w as usize, tile_h as usize);
                let planes = if (tile_w, tile_h) == (pyramid.width(), pyramid.height()) {
                    pyramid.planes().map(Cow::Borrowed)
                } else {
                    let whole = Placement {
                        resized_w: tile_w,
                        resized_h: tile_h,
                        x0: 0,
                        y0: 0,
                    };
                    pyramid.sample_planes(&whole, tw, th).map(Cow::Owned)
                };
                (planes, tw, th, offset_x as usize, offset_y as usize)
            }
        };
        Colour::Tiled {
            planes,
            width,
            height,
            mirrors,
            phase_x,
            phase_y,
            hue_shift_degrees,
        }
    }

    /// Writes the colours of scene row `y` from column `x0` on into `rgb`
    /// (one slice per channel, all of the same length).
    fn fill_row(&mut self, y: usize, x0: usize, mut rgb: [&mut [f32]; 3]) {
        let hue_shift = match self {
            Colour::Flat(c) => {
                for (out, &v) in rgb.into_iter().zip(c.iter()) {
                    out.fill(v);
                }
                return;
            }
            Colour::Tiled {
                planes,
                width: w,
                height: h,
                mirrors,
                phase_x,
                phase_y,
                hue_shift_degrees,
            } => {
                let (w, h) = (*w, *h);
                let (_, row) = mirrors.source(0, (y + *phase_y) % h, w, h);
                for (out, plane) in rgb.iter_mut().zip(planes.iter()) {
                    let row = &plane[row * w..(row + 1) * w];
                    // Copy runs of the (mirrored) image row, wrapping at its end.
                    let (mut col, mut done) = ((x0 + *phase_x) % w, 0);
                    while done < out.len() {
                        let run = (w - col).min(out.len() - done);
                        let dst = &mut out[done..done + run];
                        if mirrors.flip_x {
                            widen_reversed(&row[w - col - run..w - col], dst);
                        } else {
                            widen(&row[col..col + run], dst);
                        }
                        done += run;
                        col = 0;
                    }
                }
                *hue_shift_degrees
            }
            Colour::Stretched {
                rows,
                width: w,
                height: h,
                mirrors,
                hue_shift_degrees,
                levels,
            } => {
                let n = rgb[0].len();
                let (_, row) = mirrors.source(0, y, *w, *h);
                // A mirrored run reads the mirrored columns, right to left.
                let start = if mirrors.flip_x { *w - x0 - n } else { x0 };
                let levels = &mut levels[..n];
                for (lane, out) in rgb.iter_mut().enumerate() {
                    rows.run(lane, row, start, levels);
                    if mirrors.flip_x {
                        widen_reversed(levels, out);
                    } else {
                        widen(levels, out);
                    }
                }
                *hue_shift_degrees
            }
        };
        if let Some(degrees) = hue_shift {
            let [r, g, b] = rgb;
            rotate_hue_planes(r, g, b, degrees);
        }
    }
}

/// `out[i] = values[i]` as floats; also compiled for AVX2, picked at run
/// time (eight levels a step instead of four).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn widen(values: &[u8], out: &mut [f32]) {
    out.iter_mut().zip(values).for_each(|(o, &v)| *o = v as f32);
}

/// `out[i] = values[len - 1 - i]` as floats; also compiled for AVX2.
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn widen_reversed(values: &[u8], out: &mut [f32]) {
    out.iter_mut()
        .zip(values.iter().rev())
        .for_each(|(o, &v)| *o = v as f32);
}

/// A material's shading as drawn: its photo and how it is read.
struct Shading {
    photo: Arc<Photo>,
    record: ShadingRecord,
}

/// A shading as it is blended, before its blur: the photo channel's
/// window, made only on the runs the blur reads, and the table that
/// divides it by its maximum.
struct Shade<'a> {
    rows: ChannelRows<'a>,
    values: LevelTable,
    strength: f32,
}

impl<'a> Shade<'a> {
    /// The shading of a `w x h` scene.
    fn new(shading: &'a Shading, w: usize, h: usize) -> Self {
        let record = &shading.record;
        let mut rows = ChannelRows::new(
            &shading.photo.pyramid,
            &record.placement,
            w,
            h,
            record.channel,
        );
        let values = level_values(rows.max_level());
        Self {
            rows,
            values,
            strength: record.strength,
        }
    }

    /// Columns `x0..x0 + run.len()` of row `y` of the shading.
    fn run(&mut self, y: usize, x0: usize, run: &mut [f32]) {
        self.rows.map_run(y, x0, &self.values, run);
    }
}

/// Draws the shading of one material of a `w x h` scene (the blur is
/// applied as the material is blended).
fn draw_shading<R: Rng + ?Sized>(
    rng: &mut R,
    recipe: &CompositionRecipe,
    photos: &PhotoLibrary,
    w: usize,
    h: usize,
) -> Result<Shading, LibraryError> {
    let photo = photos.pick(|n| rng.random_range(0..n))?;
    let (placement, channel) = random_channel_placement(
        rng,
        &photo,
        w,
        h,
        recipe.p_shading_downscale,
        recipe.p_shading_hsv,
    );
    let kernel = recipe.shading_kernels[rng.random_range(0..recipe.shading_kernels.len())];
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
    Ok(Shading { photo, record })
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::RgbImage;
    use matseg_image::rgb::rotate_hue;

    /// A texture's colours through `Colour` equal the texture turned and
    /// mirrored by the image crate, then tiled or cropped (whole, or a
    /// window off its corner), then hue shifted pixel by pixel.
    #[test]
    fn texture_colours_follow_the_drawn_orientation() {
        let img = RgbImage::from_fn(7, 5, |x, y| image::Rgb([x as u8 * 30, y as u8 * 40, 9]));
        let photo = Photo::new(0, img.clone());
        let (w, h) = (11, 9);
        for bits in 0..8 {
            let (rot90, flip_x, flip_y) = (bits & 1 != 0, bits & 2 != 0, bits & 4 != 0);
            let mut want = if rot90 {
                image::imageops::rotate270(&img)
            } else {
                img.clone()
            };
            if flip_x {
                image::imageops::flip_horizontal_in_place(&mut want);
            }
            if flip_y {
                image::imageops::flip_vertical_in_place(&mut want);
            }
            let (tw, th) = want.dimensions();
            let tile = Fill::Tile {
                shrink: 1.0,
                tile_w: tw,
                tile_h: th,
                offset_x: 3,
                offset_y: 2,
            };
            let stretch = |x0, y0| Fill::Stretch {
                placement: Placement {
                    resized_w: tw,
                    resized_h: th,
                    x0,
                    y0,
                },
            };
            // Stretched at the texture's size: the scene is the texture, or
            // a window of it one pixel off its top left corner.
            let (tw_, th_) = (tw as usize, th as usize);
            let fills = [
                (tile, (w, h, 3, 2)),
                (stretch(0, 0), (tw_, th_, 0, 0)),
                (stretch(1, 1), (tw_ - 3, th_ - 1, 1, 1)),
            ];
            for ((fill, shown), hue_shift_degrees) in fills
                .into_iter()
                .flat_map(|f| [(f.clone(), None), (f, Some(137.0f32))])
            {
                let (sw, sh, ox, oy) = shown;
                // The columns and rows blended.
                let (xs, ys) = (1..10.min(sw), 1..8.min(sh));
                let source = MaterialSource::Texture {
                    texture: 0,
                    rot90,
                    flip_x,
                    flip_y,
                    fill,
                    hue_shift_degrees,
                };
                let mut colour = Colour::new(&source, Some(&photo), sw, sh);
                let span = xs.len();
                let mut rgb = [vec![0f32; span], vec![0f32; span], vec![0f32; span]];
                for y in ys {
                    colour.fill_row(y, xs.start, rgb.each_mut().map(|c| &mut c[..]));
                    for x in xs.clone() {
                        let px = want.get_pixel((x + ox) as u32 % tw, (y + oy) as u32 % th);
                        let px = px.0.map(f32::from);
                        let px = hue_shift_degrees.map_or(px, |d| rotate_hue(px, d));
                        let got = [0, 1, 2].map(|c| rgb[c][x - xs.start]);
                        assert_eq!(got, px, "bits {bits} ({x}, {y}) {hue_shift_degrees:?}");
                    }
                }
            }
        }
    }
}
