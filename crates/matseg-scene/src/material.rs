//! One material layer of a 2D scene (pipeline.md §2): a texture (tiled or stretched,
//! rotated, mirrored, hue-shifted) or a flat colour, with optional shading.

use crate::recipe::CompositionRecipe;
use matseg_extract::random_channel_placement;
use matseg_image::levels::look_up_scaled;
use matseg_image::rgb::rotate_hue_planes;
use matseg_image::{
    Channel, ChannelRows, Coverage, CoveredBlur, CropWindow, LibraryError, Mirrors, Photo,
    PhotoLibrary, Pyramid, SparsePlane, WindowRows,
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
        placement: CropWindow,
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
    pub placement: CropWindow,
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

/// Draws one material of a `w x h` scene (pipeline.md §2): a texture or a flat
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
        })
    }
}

/// One material's blending, row by row: its weight, where it is positive,
/// its colour, and its shading with the blur that streams it.
pub(crate) struct Layer<'a> {
    weight: &'a SparsePlane,
    coverage: &'a Coverage,
    colour: Colour<'a>,
    shading: Option<(Shade<'a>, CoveredBlur<'a>)>,
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
            // Unshaded, the factor is `weight * (1 + 0 * weight)`: the
            // weight itself, exactly.
            let (shade, strength) = shade.map_or((weight, 0.0), |(s, k)| (&s[x0..x1], k));
            let [r, g, b] = acc;
            let target = [&mut r[x0..x1], &mut g[x0..x1], &mut b[x0..x1]];
            match self.colour.run(y, x0, x1 - x0) {
                RunColours::Flat(c) => blend_run(target, c, weight, shade, strength),
                RunColours::Levels(c) => blend_run(target, c, weight, shade, strength),
                RunColours::Floats(c) => blend_run(target, c, weight, shade, strength),
            }
        }
    }
}

/// The colours of a run of pixels, channel by channel, as floats.
trait Colours: Copy {
    /// The same colours, cut to the first `n` pixels (a run's colours
    /// reach at least that far).
    fn cut(self, n: usize) -> Self;
    /// The colour of pixel `i`.
    fn at(self, i: usize) -> [f32; 3];
}

impl Colours for [f32; 3] {
    #[inline(always)]
    fn cut(self, _: usize) -> Self {
        self
    }
    #[inline(always)]
    fn at(self, _: usize) -> [f32; 3] {
        self
    }
}

/// 8-bit levels or floats, one slice per channel.
impl<T: Copy + Into<f32>> Colours for [&[T]; 3] {
    #[inline(always)]
    fn cut(self, n: usize) -> Self {
        self.map(|c| &c[..n])
    }
    #[inline(always)]
    fn at(self, i: usize) -> [f32; 3] {
        self.map(|c| c[i].into())
    }
}

/// `acc[c] += colour[c] * weight * ((1 - strength) + strength * shade)`
/// for each pixel of the run and channel `c`, in one pass (the colours
/// widened and the factor made in registers); also compiled for AVX2,
/// picked at run time (same arithmetic, same results).
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
fn blend_run<C: Colours>(
    acc: [&mut [f32]; 3],
    colours: C,
    weight: &[f32],
    shade: &[f32],
    strength: f32,
) {
    let n = weight.len();
    let [r, g, b] = acc;
    let (r, g, b, shade, colours) = (
        &mut r[..n],
        &mut g[..n],
        &mut b[..n],
        &shade[..n],
        colours.cut(n),
    );
    let keep = 1.0 - strength;
    for i in 0..n {
        let factor = weight[i] * (keep + strength * shade[i]);
        let [cr, cg, cb] = colours.at(i);
        r[i] += cr * factor;
        g[i] += cg * factor;
        b[i] += cb * factor;
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

/// Draws a texture's placement (pipeline.md §2); the pixels are rendered later, only
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
        let scale = CropWindow::cover_scale(tw, th, w, h);
        let (rw, rh) = CropWindow::resized_size(tw, th, scale, w, h);
        Fill::Stretch {
            placement: CropWindow {
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

/// A material's colour before shading, made run by run: its source, its
/// hue turn by `hue_shift_degrees` if any, and scratch rows (empty where
/// unused): `levels` for a texture's runs that are not read in place,
/// `floats` for a turned hue.
struct Colour<'a> {
    source: ColourSource<'a>,
    hue_shift_degrees: Option<f32>,
    levels: [Vec<u8>; 3],
    floats: [Vec<f32>; 3],
}

/// Where a material's colours come from.
enum ColourSource<'a> {
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
    },
    /// A stretched texture: a scene-sized window of it, made only on the
    /// runs blended (a material is visible on a few blocks of the scene)
    /// and read mirrored: scene pixel `(x, y)` shows the window's pixel
    /// `mirrors.source(x, y)`. `unmirrored` is scratch.
    Stretched {
        rows: WindowRows<'a>,
        width: usize,
        height: usize,
        mirrors: Mirrors,
        unmirrored: Vec<u8>,
    },
}

/// The colours of one run of a row, as [`Colour::run`] gives them.
enum RunColours<'r> {
    /// One colour for every pixel.
    Flat([f32; 3]),
    /// 8-bit levels, one slice per channel.
    Levels([&'r [u8]; 3]),
    /// Floats, one slice per channel (a texture whose hue is turned).
    Floats([&'r [f32]; 3]),
}

impl<'a> Colour<'a> {
    /// The colour of a material of a `w x h` scene from its record;
    /// `texture` is the texture's photo for a texture.
    fn new(source: &MaterialSource, texture: Option<&'a Photo>, w: usize, h: usize) -> Self {
        let with = |source: ColourSource<'a>, hue_shift_degrees: Option<f32>| {
            let read = if matches!(source, ColourSource::Flat(_)) {
                0
            } else {
                w
            };
            let turned = if hue_shift_degrees.is_some() { w } else { 0 };
            Colour {
                source,
                hue_shift_degrees,
                levels: [vec![0; read], vec![0; read], vec![0; read]],
                floats: [vec![0.0; turned], vec![0.0; turned], vec![0.0; turned]],
            }
        };
        let (fill, rot90, flip_x, flip_y, hue_shift_degrees) = match *source {
            MaterialSource::FlatColour { rgb } => {
                return with(ColourSource::Flat(rgb.map(f32::from)), None)
            }
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
        let source = match *fill {
            Fill::Stretch { placement } => {
                // The texture is mirrored before it is resized and cropped:
                // the crop of the mirrored image is the mirrored crop of the
                // unmirrored one at the mirrored corner.
                let (rw, rh) = (placement.resized_w as usize, placement.resized_h as usize);
                let (x0, y0) = (placement.x0 as usize, placement.y0 as usize);
                let window = CropWindow {
                    x0: if flip_x { rw - x0 - w } else { x0 } as u32,
                    y0: if flip_y { rh - y0 - h } else { y0 } as u32,
                    ..placement
                };
                ColourSource::Stretched {
                    rows: WindowRows::new(pyramid, &window, w, h),
                    width: w,
                    height: h,
                    mirrors,
                    unmirrored: vec![0; w],
                }
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
                    let whole = CropWindow {
                        resized_w: tile_w,
                        resized_h: tile_h,
                        x0: 0,
                        y0: 0,
                    };
                    pyramid.sample_planes(&whole, tw, th).map(Cow::Owned)
                };
                ColourSource::Tiled {
                    planes,
                    width: tw,
                    height: th,
                    mirrors,
                    phase_x: offset_x as usize,
                    phase_y: offset_y as usize,
                }
            }
        };
        with(source, hue_shift_degrees)
    }

    /// The colours of columns `x0..x0 + n` of scene row `y`: a tile's row
    /// read in place where the run neither wraps nor is mirrored, else
    /// levels copied into scratch; floats when the hue is turned.
    fn run(&mut self, y: usize, x0: usize, n: usize) -> RunColours<'_> {
        let Colour {
            source,
            hue_shift_degrees,
            levels: scratch,
            floats,
        } = self;
        let levels: [&[u8]; 3] = match source {
            ColourSource::Flat(c) => return RunColours::Flat(*c),
            ColourSource::Tiled {
                planes,
                width: w,
                height: h,
                mirrors,
                phase_x,
                phase_y,
            } => {
                let (w, h) = (*w, *h);
                let (_, row) = mirrors.source(0, (y + *phase_y) % h, w, h);
                let first = (x0 + *phase_x) % w;
                if !mirrors.flip_x && first + n <= w {
                    planes.each_ref().map(|p| &p[row * w + first..][..n])
                } else {
                    for (out, plane) in scratch.iter_mut().zip(planes.iter()) {
                        let row = &plane[row * w..(row + 1) * w];
                        // Copy runs of the (mirrored) image row, wrapping at its end.
                        let (mut col, mut done) = (first, 0);
                        while done < n {
                            let run = (w - col).min(n - done);
                            let dst = &mut out[done..done + run];
                            if mirrors.flip_x {
                                copy_reversed(&row[w - col - run..w - col], dst);
                            } else {
                                dst.copy_from_slice(&row[col..col + run]);
                            }
                            done += run;
                            col = 0;
                        }
                    }
                    scratch.each_ref().map(|l| &l[..n])
                }
            }
            ColourSource::Stretched {
                rows,
                width: w,
                height: h,
                mirrors,
                unmirrored,
            } => {
                let (_, row) = mirrors.source(0, y, *w, *h);
                // A mirrored run reads the mirrored columns, right to left.
                let start = if mirrors.flip_x { *w - x0 - n } else { x0 };
                for (lane, out) in scratch.iter_mut().enumerate() {
                    if mirrors.flip_x {
                        rows.run(lane, row, start, &mut unmirrored[..n]);
                        copy_reversed(&unmirrored[..n], &mut out[..n]);
                    } else {
                        rows.run(lane, row, start, &mut out[..n]);
                    }
                }
                scratch.each_ref().map(|l| &l[..n])
            }
        };
        let Some(degrees) = *hue_shift_degrees else {
            return RunColours::Levels(levels);
        };
        for (out, levels) in floats.iter_mut().zip(levels) {
            widen(levels, &mut out[..n]);
        }
        let [r, g, b] = floats.each_mut().map(|c| &mut c[..n]);
        rotate_hue_planes(r, g, b, degrees);
        RunColours::Floats(floats.each_ref().map(|c| &c[..n]))
    }
}

/// `out[i] = values[i]` as floats; also compiled for AVX2, picked at run
/// time (eight levels a step instead of four).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn widen(values: &[u8], out: &mut [f32]) {
    out.iter_mut().zip(values).for_each(|(o, &v)| *o = v as f32);
}

/// `out[i] = values[len - 1 - i]`; also compiled for AVX2 (byte shuffles).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn copy_reversed(values: &[u8], out: &mut [u8]) {
    out.iter_mut()
        .zip(values.iter().rev())
        .for_each(|(o, &v)| *o = v);
}

/// A material's shading as drawn: its photo and how it is read.
struct Shading {
    photo: Arc<Photo>,
    record: ShadingRecord,
}

/// A shading as it is blended, before its blur: the photo channel's
/// window, made only on the runs the blur reads, and its maximum, which
/// divides it (pipeline.md §2).
struct Shade<'a> {
    rows: ChannelRows<'a>,
    max_level: u8,
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
        Self {
            max_level: rows.max_level(),
            rows,
            strength: record.strength,
        }
    }

    /// Columns `x0..x0 + run.len()` of row `y` of the shading: each level
    /// divided by the maximum, as [`matseg_image::level_values`] has it.
    fn run(&mut self, y: usize, x0: usize, run: &mut [f32]) {
        let levels = self.rows.levels(y, x0, run.len());
        look_up_scaled(levels, self.max_level, run);
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
                placement: CropWindow {
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
                // The runs blended: a long one (a tile's wraps), and short
                // ones (a tile's row read in place when not mirrored).
                let runs = [(1, 10), (1, 3), (4, 6)].map(|(x0, x1)| (x0, x1.min(sw)));
                let source = MaterialSource::Texture {
                    texture: 0,
                    rot90,
                    flip_x,
                    flip_y,
                    fill,
                    hue_shift_degrees,
                };
                let mut colour = Colour::new(&source, Some(&photo), sw, sh);
                for ((x0, x1), y) in runs
                    .into_iter()
                    .flat_map(|r| (1..8.min(sh)).map(move |y| (r, y)))
                {
                    if x0 >= x1 {
                        continue;
                    }
                    let run = colour.run(y, x0, x1 - x0);
                    let colour_at = |i| match run {
                        RunColours::Flat(c) => c.at(i),
                        RunColours::Levels(c) => c.at(i),
                        RunColours::Floats(c) => c.at(i),
                    };
                    for x in x0..x1 {
                        let px = want.get_pixel((x + ox) as u32 % tw, (y + oy) as u32 % th);
                        let px = px.0.map(f32::from);
                        let px = hue_shift_degrees.map_or(px, |d| rotate_hue(px, d));
                        let got = colour_at(x - x0);
                        assert_eq!(got, px, "bits {bits} ({x}, {y}) {hue_shift_degrees:?}");
                    }
                }
            }
        }
    }

    /// `start` (each channel) after [`blend_run`] of `colours`.
    fn blended<C: Colours>(
        start: &[f32],
        colours: C,
        weight: &[f32],
        shade: &[f32],
        strength: f32,
    ) -> [Vec<f32>; 3] {
        let mut acc = [start.to_vec(), start.to_vec(), start.to_vec()];
        blend_run(
            acc.each_mut().map(|a| &mut a[..]),
            colours,
            weight,
            shade,
            strength,
        );
        acc
    }

    /// A run blends colour times weight, times the shade factor when
    /// shaded; unshaded (strength 0, the weight standing in for the shade)
    /// exactly colour times weight. Every kind of colours, on runs longer
    /// and shorter than a vector.
    #[test]
    fn runs_blend_colour_times_weight_and_shade() {
        for n in [1, 7, 8, 9, 37] {
            let weight: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).fract()).collect();
            let shade: Vec<f32> = (0..n).map(|i| (i as f32 * 0.61 + 0.2).fract()).collect();
            let levels: [Vec<u8>; 3] =
                [0, 1, 2].map(|c| (0..n).map(|i| (i * 41 + c * 90) as u8).collect());
            let floats = levels
                .each_ref()
                .map(|l| l.iter().map(|&v| v as f32 * 0.5).collect::<Vec<f32>>());
            let start: Vec<f32> = (0..n).map(|i| i as f32 * 3.0).collect();
            for (shade, strength) in [(&shade, 0.7f32), (&weight, 0.0)] {
                let check = |acc: [Vec<f32>; 3], at: &dyn Fn(usize) -> [f32; 3]| {
                    for i in 0..n {
                        let factor = if strength == 0.0 {
                            weight[i]
                        } else {
                            weight[i] * ((1.0 - strength) + strength * shade[i])
                        };
                        for (c, plane) in acc.iter().enumerate() {
                            let want = start[i] + at(i)[c] * factor;
                            assert_eq!(plane[i], want, "n {n} pixel {i}");
                        }
                    }
                };
                let flat = [3.0f32, 100.0, 255.0];
                check(blended(&start, flat, &weight, shade, strength), &|_| flat);
                let l = levels.each_ref().map(|l| &l[..]);
                check(blended(&start, l, &weight, shade, strength), &|i| l.at(i));
                let f = floats.each_ref().map(|f| &f[..]);
                check(blended(&start, f, &weight, shade, strength), &|i| f.at(i));
            }
        }
    }
}
