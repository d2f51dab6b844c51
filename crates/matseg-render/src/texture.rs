//! Image textures for shading: 8-bit storage (a 1K PBR set stays ~5 MB),
//! bilinear lookups with wrap-around, sRGB decoding for colour maps, and
//! the placement (scale, rotation, offset) of a texture on a surface.

use matseg_image::lab::linear_table;
use serde::{Deserialize, Serialize};

/// An 8-bit image with 1 or 3 channels, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: usize,
    height: usize,
    channels: usize,
    data: Vec<u8>,
}

/// Linear value to an sRGB-encoded value in [0, 1].
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

impl Texture {
    /// From an RGB image (its pixels are moved, not copied).
    pub fn from_rgb(img: image::RgbImage) -> Self {
        let (w, h) = (img.width() as usize, img.height() as usize);
        Texture::from_raw(w, h, 3, img.into_raw())
    }

    /// From a greyscale image (its pixels are moved, not copied).
    pub fn from_grey(img: image::GrayImage) -> Self {
        let (w, h) = (img.width() as usize, img.height() as usize);
        Texture::from_levels(w, h, img.into_raw())
    }

    /// From raw single-channel levels.
    pub fn from_levels(width: usize, height: usize, data: Vec<u8>) -> Self {
        Texture::from_raw(width, height, 1, data)
    }

    fn from_raw(width: usize, height: usize, channels: usize, data: Vec<u8>) -> Self {
        assert_eq!(
            data.len(),
            width * height * channels,
            "texels fill the image"
        );
        Texture {
            width,
            height,
            channels,
            data,
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.data.len()
    }

    /// Width in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The four texels around (u, v) (wrapped) and their bilinear weights.
    /// v = 0 is the bottom row, as in OBJ and Blender.
    #[inline]
    fn taps(&self, u: f32, v: f32) -> ([usize; 4], [f32; 4]) {
        // Wrap into one repeat first (no integer division in this hot path):
        // the left/top tap is then in -1..n-1 and the right/bottom one in 0..n.
        let (u, v) = (u - u.floor(), v - v.floor());
        let x = u * self.width as f32 - 0.5;
        let y = (1.0 - v) * self.height as f32 - 0.5;
        let (fx, fy) = (x.floor(), y.floor());
        let (tx, ty) = (x - fx, y - fy);
        let wrap = |i: f32, n: usize| {
            let i = i as i64;
            if i < 0 {
                n - 1
            } else if i as usize >= n {
                i as usize - n
            } else {
                i as usize
            }
        };
        let (x0, y0) = (wrap(fx, self.width), wrap(fy, self.height));
        let next = |i: usize, n: usize| if i + 1 == n { 0 } else { i + 1 };
        let (x1, y1) = (next(x0, self.width), next(y0, self.height));
        let c = self.channels;
        (
            [
                (y0 * self.width + x0) * c,
                (y0 * self.width + x1) * c,
                (y1 * self.width + x0) * c,
                (y1 * self.width + x1) * c,
            ],
            [
                (1.0 - tx) * (1.0 - ty),
                tx * (1.0 - ty),
                (1.0 - tx) * ty,
                tx * ty,
            ],
        )
    }

    /// Channel `c`'s value in [0, 1] at (u, v), through `table`.
    #[inline]
    fn lookup(&self, u: f32, v: f32, c: usize, table: impl Fn(u8) -> f32) -> f32 {
        let (idx, w) = self.taps(u, v);
        let c = c.min(self.channels - 1);
        (0..4).map(|k| w[k] * table(self.data[idx[k] + c])).sum()
    }

    /// A scalar in [0, 1] (the first channel) at (u, v).
    #[inline]
    pub fn scalar(&self, u: f32, v: f32) -> f32 {
        self.lookup(u, v, 0, |l| l as f32 * (1.0 / 255.0))
    }

    /// The stored values in [0, 1] at (u, v), without colour decoding (for
    /// normal maps).
    #[inline]
    pub fn raw_rgb(&self, u: f32, v: f32) -> [f32; 3] {
        std::array::from_fn(|c| self.lookup(u, v, c, |l| l as f32 * (1.0 / 255.0)))
    }

    /// Linear RGB at (u, v) of an sRGB colour texture.
    #[inline]
    pub fn linear_rgb(&self, u: f32, v: f32) -> [f32; 3] {
        let t = linear_table();
        std::array::from_fn(|c| self.lookup(u, v, c, |l| t[l as usize]))
    }
}

/// Where a texture sits on a surface: texture coordinates are the surface's
/// UVs turned by `rotation_deg`, divided by `scale`, then shifted by
/// `offset` (so a scale of 0.1 repeats the texture ten times).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Placement {
    /// Size of one texture repeat in UV units.
    pub scale: f32,
    /// Rotation in degrees.
    #[serde(default)]
    pub rotation_deg: f32,
    /// Shift in texture units.
    #[serde(default)]
    pub offset: [f32; 2],
}

impl Default for Placement {
    fn default() -> Self {
        Placement {
            scale: 1.0,
            rotation_deg: 0.0,
            offset: [0.0, 0.0],
        }
    }
}

impl Placement {
    /// Texture coordinates for surface coordinates `uv`.
    #[inline]
    pub fn apply(&self, [u, v]: [f32; 2]) -> [f32; 2] {
        let (s, c) = self.rotation_deg.to_radians().sin_cos();
        let k = 1.0 / self.scale;
        [
            (c * u - s * v) * k + self.offset[0],
            (s * u + c * v) * k + self.offset[1],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookups_interpolate_and_wrap() {
        // 2x1 texture: black then white.
        let t = Texture::from_levels(2, 1, vec![0, 255]);
        assert_eq!(t.scalar(0.25, 0.5), 0.0, "texel centre");
        assert_eq!(t.scalar(0.75, 0.5), 1.0);
        assert!(
            (t.scalar(0.5, 0.5) - 0.5).abs() < 1e-6,
            "between the texels"
        );
        assert!(
            (t.scalar(0.0, 0.5) - 0.5).abs() < 1e-6,
            "wraps to the other edge"
        );
        assert_eq!(t.scalar(1.25, 0.5), t.scalar(0.25, 0.5));
        assert_eq!(t.scalar(-0.75, 0.5), t.scalar(0.25, 0.5));
    }

    #[test]
    fn colour_is_decoded_from_srgb() {
        let img = image::RgbImage::from_pixel(1, 1, image::Rgb([255, 188, 0]));
        let t = Texture::from_rgb(img);
        let [r, g, b] = t.linear_rgb(0.3, 0.3);
        assert!((r - 1.0).abs() < 1e-6 && b == 0.0);
        assert!((g - 0.5029).abs() < 1e-3, "{g}");
        assert!((linear_to_srgb(g) * 255.0 - 188.0).abs() < 0.5);
    }

    #[test]
    fn placement_scales_turns_and_shifts() {
        let p = Placement {
            scale: 0.5,
            rotation_deg: 90.0,
            offset: [0.25, 0.0],
        };
        let [u, v] = p.apply([1.0, 0.0]);
        assert!((u - 0.25).abs() < 1e-6 && (v - 2.0).abs() < 1e-6, "{u} {v}");
    }
}
