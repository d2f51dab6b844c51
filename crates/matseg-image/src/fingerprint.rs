//! Photo fingerprints: whether two image files hold the same photo,
//! whatever their size, compression or a quarter turn or flip. A photo's
//! fingerprint is its grey level averaged over a 16 x 16 grid of equal
//! cells spanning the whole image, less its mean, scaled to unit length;
//! two photos' similarity is the largest correlation of their grids over
//! the eight rotations and mirror images. A photo and a resized, recompressed
//! copy of it score above 0.99; different photos of the packages this
//! project draws from score below 0.93 (docs/assets.md).

use image::RgbImage;

/// Cells a side of the grid.
pub const GRID: usize = 16;
/// Similarity at and above which two photos count as the same one.
pub const SAME_PHOTO: f32 = 0.97;

/// A photo's fingerprint: `GRID * GRID` values, row by row, quantised to
/// signed bytes (the largest magnitude at 127).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fingerprint([i8; GRID * GRID]);

impl Fingerprint {
    /// The fingerprint of `image`.
    pub fn of(image: &RgbImage) -> Self {
        let (w, h) = (image.width() as usize, image.height() as usize);
        let mut sums = [0f64; GRID * GRID];
        let mut counts = [0u32; GRID * GRID];
        for (x, y, p) in image.enumerate_pixels() {
            let cell = (y as usize * GRID / h.max(1)) * GRID + x as usize * GRID / w.max(1);
            sums[cell] += (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0;
            counts[cell] += 1;
        }
        let means: Vec<f64> = sums
            .iter()
            .zip(counts)
            .map(|(s, c)| s / c.max(1) as f64)
            .collect();
        let mean = means.iter().sum::<f64>() / means.len() as f64;
        let largest = means
            .iter()
            .map(|m| (m - mean).abs())
            .fold(0.0, f64::max)
            .max(1e-9);
        let mut values = [0i8; GRID * GRID];
        for (v, m) in values.iter_mut().zip(&means) {
            *v = ((m - mean) / largest * 127.0).round() as i8;
        }
        Self(values)
    }

    /// The fingerprint as 512 hex digits (for catalogues and tables).
    pub fn to_hex(&self) -> String {
        self.0.iter().map(|&v| format!("{:02x}", v as u8)).collect()
    }

    /// A fingerprint written by [`Fingerprint::to_hex`]; `None` for text
    /// that is not one.
    pub fn from_hex(text: &str) -> Option<Self> {
        let text = text.trim();
        if text.len() != 2 * GRID * GRID || !text.is_ascii() {
            return None;
        }
        let mut values = [0i8; GRID * GRID];
        for (i, v) in values.iter_mut().enumerate() {
            *v = u8::from_str_radix(&text[2 * i..2 * i + 2], 16).ok()? as i8;
        }
        Some(Self(values))
    }

    /// The value at grid cell (`x`, `y`) of this fingerprint turned by
    /// `variant` (0-3: quarter turns; 4-7: the same, mirrored).
    fn at(&self, variant: usize, x: usize, y: usize) -> f32 {
        let n = GRID - 1;
        let (x, y) = if variant >= 4 { (n - x, y) } else { (x, y) };
        let (x, y) = match variant % 4 {
            0 => (x, y),
            1 => (y, n - x),
            2 => (n - x, n - y),
            _ => (n - y, x),
        };
        self.0[y * GRID + x] as f32
    }

    /// The correlation of two fingerprints, at the turn or mirror image of
    /// `other` that matches best: 1 for the same photo, near 0 for
    /// unrelated ones.
    pub fn similarity(&self, other: &Fingerprint) -> f32 {
        let norm = |f: &Fingerprint| f.0.iter().map(|&v| (v as f32).powi(2)).sum::<f32>().sqrt();
        let scale = (norm(self) * norm(other)).max(1e-9);
        (0..8)
            .map(|variant| {
                let mut dot = 0.0;
                for y in 0..GRID {
                    for x in 0..GRID {
                        dot += self.0[y * GRID + x] as f32 * other.at(variant, x, y);
                    }
                }
                dot / scale
            })
            .fold(f32::MIN, f32::max)
    }

    /// Whether the two are fingerprints of the same photo ([`SAME_PHOTO`]).
    pub fn same_photo(&self, other: &Fingerprint) -> bool {
        self.similarity(other) >= SAME_PHOTO
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::imageops::{self, FilterType};

    /// A 300x200 scene of soft blobs and stripes.
    fn photo(seed: u32) -> RgbImage {
        RgbImage::from_fn(300, 200, |x, y| {
            let (fx, fy) = (x as f32 / 300.0, y as f32 / 200.0);
            let s = seed as f32;
            let v = ((fx * (3.0 + s) + fy * 2.0).sin() * (fy * (5.0 - s) - fx).cos() + 1.0) * 100.0;
            image::Rgb([v as u8, (v * 0.8) as u8 + (x % 7) as u8, (255.0 * fy) as u8])
        })
    }

    #[test]
    fn resized_recompressed_turned_copies_are_the_same_photo() {
        let original = photo(1);
        let print = Fingerprint::of(&original);
        let small = imageops::resize(&original, 120, 80, FilterType::Lanczos3);
        let mut jpeg = Vec::new();
        image::DynamicImage::ImageRgb8(small)
            .write_to(
                &mut std::io::Cursor::new(&mut jpeg),
                image::ImageFormat::Jpeg,
            )
            .unwrap();
        let copy = image::load_from_memory(&jpeg).unwrap().into_rgb8();
        assert!(print.similarity(&Fingerprint::of(&copy)) > 0.99);
        for turned in [
            imageops::rotate90(&original),
            imageops::rotate180(&original),
            imageops::rotate270(&original),
            imageops::flip_horizontal(&original),
            imageops::rotate90(&imageops::flip_vertical(&original)),
        ] {
            let s = print.similarity(&Fingerprint::of(&turned));
            assert!(s > 0.999, "{s}");
        }
        let other = Fingerprint::of(&photo(2));
        assert!(!print.same_photo(&other), "{}", print.similarity(&other));
        assert_eq!(Fingerprint::from_hex(&print.to_hex()), Some(print));
        assert_eq!(Fingerprint::from_hex("00ff"), None);
    }
}
