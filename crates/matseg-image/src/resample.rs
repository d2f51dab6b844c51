//! Resampling through a mip pyramid: "resize to W'xH', then crop a window" done
//! in one pass that only computes the output pixels.

use crate::channel::Channel;
use crate::plane::Plane;
use crate::rgb::RgbF32;
use image::RgbImage;
use serde::{Deserialize, Serialize};

/// Levels stop once the next one would have a side shorter than this.
const MIN_LEVEL_SIDE: u32 = 32;

/// An 8-bit RGB image and its successive 2x2 box-averaged halvings, so that
/// strong downscaling reads a level close to the target scale (no aliasing).
#[derive(Clone, Debug)]
pub struct Pyramid {
    levels: Vec<RgbImage>,
}

impl Pyramid {
    /// Builds the pyramid of `img` (level 0 is `img` itself).
    pub fn new(img: RgbImage) -> Self {
        let mut levels = vec![img];
        loop {
            let last = levels.last().expect("at least one level");
            let (w, h) = (last.width() / 2, last.height() / 2);
            if w.min(h) < MIN_LEVEL_SIDE {
                break;
            }
            let next = RgbImage::from_fn(w, h, |x, y| {
                let mut px = [0u8; 3];
                for (c, out) in px.iter_mut().enumerate() {
                    let sum: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                        .iter()
                        .map(|&(dx, dy)| last.get_pixel(2 * x + dx, 2 * y + dy)[c] as u32)
                        .sum();
                    *out = ((sum + 2) / 4) as u8;
                }
                image::Rgb(px)
            });
            levels.push(next);
        }
        Self { levels }
    }

    /// The full-resolution image.
    pub fn base(&self) -> &RgbImage {
        &self.levels[0]
    }

    /// Width of the full-resolution image.
    pub fn width(&self) -> u32 {
        self.levels[0].width()
    }

    /// Height of the full-resolution image.
    pub fn height(&self) -> u32 {
        self.levels[0].height()
    }

    /// Bytes held by all levels.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.as_raw().len()).sum()
    }

    /// Samples the window `placement` selects, `out_w x out_h` pixels, mapping
    /// each bilinearly interpolated RGB (0..255) pixel through `f`.
    pub fn sample_with<T>(
        &self,
        placement: &Placement,
        out_w: usize,
        out_h: usize,
        f: impl Fn([f32; 3]) -> T,
    ) -> Vec<T> {
        self.sample_lanes(
            placement,
            out_w,
            out_h,
            |p| [p[0] as f32, p[1] as f32, p[2] as f32],
            f,
        )
    }

    /// The sampling core: `pick` takes the `N` lanes to interpolate from an
    /// RGB8 pixel (one colour channel, or all three), `f` maps the result.
    fn sample_lanes<const N: usize, T>(
        &self,
        placement: &Placement,
        out_w: usize,
        out_h: usize,
        pick: impl Fn(&[u8]) -> [f32; N],
        f: impl Fn([f32; N]) -> T,
    ) -> Vec<T> {
        let fx = self.width() as f64 / placement.resized_w as f64;
        let fy = self.height() as f64 / placement.resized_h as f64;
        let mut out = Vec::with_capacity(out_w * out_h);
        if fx == 1.0 && fy == 1.0 {
            // Native resolution: a plain crop, no interpolation.
            let img = &self.levels[0];
            let stride = img.width() as usize * 3;
            let raw = img.as_raw();
            for y in 0..out_h {
                let row = (y + placement.y0 as usize) * stride + placement.x0 as usize * 3;
                out.extend(
                    raw[row..row + out_w * 3]
                        .chunks_exact(3)
                        .map(|p| f(pick(p))),
                );
            }
            return out;
        }
        let (img, cols, rows) = self.grid(placement, out_w, out_h);
        // Source columns the window touches; rows are blended over this span only.
        let first = cols.first().map_or(0, |c| c.0);
        let last = cols.last().map_or(0, |c| c.1);
        let raw = img.as_raw();
        let stride = img.width() as usize * 3;
        let mut blended = vec![[0f32; N]; last - first + 1];
        for &(y0, y1, wy) in &rows {
            let r0 = &raw[y0 * stride + first * 3..y0 * stride + (last + 1) * 3];
            let r1 = &raw[y1 * stride + first * 3..y1 * stride + (last + 1) * 3];
            for ((b, a), c) in blended
                .iter_mut()
                .zip(r0.chunks_exact(3))
                .zip(r1.chunks_exact(3))
            {
                let (a, c) = (pick(a), pick(c));
                for lane in 0..N {
                    b[lane] = a[lane] + (c[lane] - a[lane]) * wy;
                }
            }
            out.extend(cols.iter().map(|&(x0, x1, wx)| {
                let (a, b) = (blended[x0 - first], blended[x1 - first]);
                f(std::array::from_fn(|lane| {
                    a[lane] + (b[lane] - a[lane]) * wx
                }))
            }));
        }
        out
    }

    /// The pyramid level to read for `placement` and the bilinear taps of
    /// every output column and row on it.
    fn grid(
        &self,
        placement: &Placement,
        out_w: usize,
        out_h: usize,
    ) -> (&RgbImage, Vec<Tap>, Vec<Tap>) {
        let fx = self.width() as f64 / placement.resized_w as f64;
        let fy = self.height() as f64 / placement.resized_h as f64;
        let shrink = fx.min(fy);
        let level = if shrink >= 2.0 {
            (shrink.log2().floor() as usize).min(self.levels.len() - 1)
        } else {
            0
        };
        let img = &self.levels[level];
        let step = (1u64 << level) as f64;
        let cols = axis_taps(out_w, placement.x0, fx / step, img.width());
        let rows = axis_taps(out_h, placement.y0, fy / step, img.height());
        (img, cols, rows)
    }

    /// A sampler for single pixels of the window `placement` selects, for
    /// callers that need only some of them.
    pub fn point_sampler(
        &self,
        placement: &Placement,
        out_w: usize,
        out_h: usize,
    ) -> PointSampler<'_> {
        let (img, cols, rows) = self.grid(placement, out_w, out_h);
        PointSampler { img, cols, rows }
    }

    /// The selected window as a float RGB image.
    pub fn sample_rgb(&self, placement: &Placement, out_w: usize, out_h: usize) -> RgbF32 {
        RgbF32 {
            width: out_w,
            height: out_h,
            data: self.sample_with(placement, out_w, out_h, |p| p),
        }
    }

    /// One channel of the selected window, on the channel's full range `[0, 1]`.
    pub fn sample_channel(
        &self,
        placement: &Placement,
        out_w: usize,
        out_h: usize,
        channel: Channel,
    ) -> Plane {
        // Colour channels interpolate one lane; HSV needs all three. One
        // closure per channel, so each loop is specialised.
        let one = |lane: usize| move |p: &[u8]| [p[lane] as f32];
        let unit = |v: [f32; 1]| v[0] / 255.0;
        let data = match channel {
            Channel::R => self.sample_lanes(placement, out_w, out_h, one(0), unit),
            Channel::G => self.sample_lanes(placement, out_w, out_h, one(1), unit),
            Channel::B => self.sample_lanes(placement, out_w, out_h, one(2), unit),
            Channel::H => self.sample_with(placement, out_w, out_h, |p| Channel::H.value(p)),
            Channel::S => self.sample_with(placement, out_w, out_h, |p| Channel::S.value(p)),
            Channel::V => self.sample_with(placement, out_w, out_h, |p| Channel::V.value(p)),
        };
        Plane::from_vec(out_w, out_h, data)
    }

    /// The whole image resized to `w x h`.
    pub fn resize_rgb(&self, w: usize, h: usize) -> RgbF32 {
        let whole = Placement {
            resized_w: w as u32,
            resized_h: h as u32,
            x0: 0,
            y0: 0,
        };
        self.sample_rgb(&whole, w, h)
    }
}

/// Two source indices and the weight of the second.
type Tap = (usize, usize, f32);

/// Bilinear samples of single pixels of a placed window (see
/// [`Pyramid::point_sampler`]); equal to the same pixels of [`Pyramid::sample_rgb`].
pub struct PointSampler<'a> {
    img: &'a RgbImage,
    cols: Vec<Tap>,
    rows: Vec<Tap>,
}

impl PointSampler<'_> {
    /// The RGB (0..255) value of window pixel `(x, y)`.
    #[inline]
    pub fn rgb(&self, x: usize, y: usize) -> [f32; 3] {
        let (x0, x1, wx) = self.cols[x];
        let (y0, y1, wy) = self.rows[y];
        let raw = self.img.as_raw();
        let stride = self.img.width() as usize * 3;
        let px = |xx: usize, yy: usize, c: usize| raw[yy * stride + xx * 3 + c] as f32;
        std::array::from_fn(|c| {
            let a = px(x0, y0, c) + (px(x0, y1, c) - px(x0, y0, c)) * wy;
            let b = px(x1, y0, c) + (px(x1, y1, c) - px(x1, y0, c)) * wy;
            a + (b - a) * wx
        })
    }
}

/// For each output index along one axis: the two source indices and the
/// weight of the second, for a source sampled at `step` pixels per output pixel.
fn axis_taps(n: usize, offset: u32, step: f64, src_len: u32) -> Vec<Tap> {
    let last = src_len as i64 - 1;
    (0..n)
        .map(|i| {
            let u = ((i as f64 + offset as f64 + 0.5) * step - 0.5).max(0.0);
            let i0 = (u.floor() as i64).min(last);
            let i1 = (i0 + 1).min(last);
            (
                i0 as usize,
                i1 as usize,
                (u - i0 as f64).clamp(0.0, 1.0) as f32,
            )
        })
        .collect()
}

/// Where a scene-sized window comes from: resize the source to
/// `resized_w x resized_h`, then crop at `(x0, y0)` in resized pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Placement {
    /// Width the source is resized to.
    pub resized_w: u32,
    /// Height the source is resized to.
    pub resized_h: u32,
    /// Left of the crop window, in resized pixels.
    pub x0: u32,
    /// Top of the crop window, in resized pixels.
    pub y0: u32,
}

impl Placement {
    /// The smallest uniform scale at which a `src` image covers an `out` window.
    pub fn cover_scale(src_w: u32, src_h: u32, out_w: usize, out_h: usize) -> f64 {
        (out_w as f64 / src_w as f64).max(out_h as f64 / src_h as f64)
    }

    /// The resized size for `scale`, never smaller than the window.
    pub fn resized_size(
        src_w: u32,
        src_h: u32,
        scale: f64,
        out_w: usize,
        out_h: usize,
    ) -> (u32, u32) {
        let w = ((src_w as f64 * scale).round() as u32).max(out_w as u32);
        let h = ((src_h as f64 * scale).round() as u32).max(out_h as u32);
        (w, h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, 100]))
    }

    #[test]
    fn identity_placement_reproduces_the_image() {
        let img = gradient(40, 30);
        let p = Pyramid::new(img.clone());
        let place = Placement {
            resized_w: 40,
            resized_h: 30,
            x0: 5,
            y0: 7,
        };
        let out = p.sample_rgb(&place, 10, 8);
        for y in 0..8 {
            for x in 0..10 {
                let src = img.get_pixel(x as u32 + 5, y as u32 + 7);
                let got = out.data[y * 10 + x];
                for c in 0..3 {
                    assert!((got[c] - src[c] as f32).abs() < 1e-4);
                }
            }
        }
    }

    #[test]
    fn point_sampler_matches_the_whole_window() {
        let p = Pyramid::new(gradient(90, 70));
        for place in [
            Placement {
                resized_w: 200,
                resized_h: 156,
                x0: 13,
                y0: 40,
            },
            Placement {
                resized_w: 90,
                resized_h: 70,
                x0: 3,
                y0: 2,
            },
            Placement {
                resized_w: 30,
                resized_h: 23,
                x0: 1,
                y0: 0,
            },
        ] {
            let whole = p.sample_rgb(&place, 25, 20);
            let points = p.point_sampler(&place, 25, 20);
            for y in 0..20 {
                for x in 0..25 {
                    let (a, b) = (whole.data[y * 25 + x], points.rgb(x, y));
                    assert!(
                        (0..3).all(|c| (a[c] - b[c]).abs() < 1e-3),
                        "{place:?} ({x}, {y}): {a:?} vs {b:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn pyramid_levels_halve_and_average() {
        let img = RgbImage::from_fn(128, 64, |x, _| image::Rgb([(x % 2) as u8 * 200, 0, 0]));
        let p = Pyramid::new(img);
        assert_eq!(p.levels.len(), 2);
        assert_eq!(p.levels[1].dimensions(), (64, 32));
        assert!(p.levels[1].pixels().all(|px| px[0] == 100));
        // A 4x downscale reads the averaged level, not aliased columns.
        let out = p.resize_rgb(32, 16);
        assert!(out.data.iter().all(|px| (px[0] - 100.0).abs() < 1e-3));
    }

    #[test]
    fn cover_scale_covers_the_window() {
        let s = Placement::cover_scale(300, 200, 600, 600);
        assert_eq!(s, 3.0);
        assert_eq!(Placement::resized_size(300, 200, s, 600, 600), (900, 600));
    }
}
