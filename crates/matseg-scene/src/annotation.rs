//! Annotations as written to disk: weights quantised to 8 bits so that masks
//! and background sum to exactly 255, and colour previews.

use matseg_image::plane::round_to_u8;
use matseg_image::Plane;

/// Per-pixel 8-bit masks, background and ROI.
#[derive(Clone, Debug, PartialEq)]
pub struct QuantisedAnnotation {
    /// One mask per material, row-major.
    pub masks: Vec<Vec<u8>>,
    /// Background weight.
    pub background: Vec<u8>,
    /// Region of interest: `255 - background`, equal to the sum of the masks.
    pub roi: Vec<u8>,
}

/// Quantises weights to 8 bits by largest remainder: per pixel, background
/// plus masks sum to exactly 255 and each value is within 1 of `255 * weight`.
pub fn quantise_weights(weights: &[Plane], background: &Plane) -> QuantisedAnnotation {
    let n = background.len();
    let floor = |p: &Plane| -> Vec<u8> {
        p.data
            .iter()
            .map(|&v| (v * 255.0).clamp(0.0, 255.0) as u8)
            .collect()
    };
    // Floor every plane (vectorisable), then hand the units the floors lost to
    // the largest remainders, only on the pixels that lost any.
    let mut bg = floor(background);
    let mut masks: Vec<Vec<u8>> = weights.iter().map(floor).collect();
    let mut totals: Vec<u32> = bg.iter().map(|&v| v as u32).collect();
    for m in &masks {
        for (t, &v) in totals.iter_mut().zip(m) {
            *t += v as u32;
        }
    }
    for i in 0..n {
        for _ in 0..255u32.saturating_sub(totals[i]) {
            // Candidate j = 0 is the background, j > 0 material j - 1; first wins ties.
            let remainder = |plane: &Plane, q: u8| {
                if q < 255 {
                    plane.data[i] * 255.0 - q as f32
                } else {
                    f32::NEG_INFINITY
                }
            };
            let mut best = (remainder(background, bg[i]), 0);
            for (j, (w, m)) in weights.iter().zip(&masks).enumerate() {
                let r = remainder(w, m[i]);
                if r > best.0 {
                    best = (r, j + 1);
                }
            }
            match best.1 {
                0 => bg[i] += 1,
                j => masks[j - 1][i] += 1,
            }
        }
    }
    let roi = bg.iter().map(|&b| 255 - b).collect();
    QuantisedAnnotation {
        masks,
        background: bg,
        roi,
    }
}

/// Distinct colours for material previews, in material order.
pub const PALETTE: [[u8; 3]; 20] = [
    [230, 25, 75],
    [60, 180, 75],
    [0, 130, 200],
    [255, 225, 25],
    [245, 130, 48],
    [145, 30, 180],
    [70, 240, 240],
    [240, 50, 230],
    [210, 245, 60],
    [250, 190, 212],
    [0, 128, 128],
    [220, 190, 255],
    [170, 110, 40],
    [255, 250, 200],
    [128, 0, 0],
    [170, 255, 195],
    [128, 128, 0],
    [255, 215, 180],
    [0, 0, 128],
    [128, 128, 128],
];

/// A colour preview of soft weights (row-major, `width x height`): each
/// material in its palette colour, mixtures as mixed colours, background black.
pub fn colorize(width: usize, height: usize, weights: &[&[f32]]) -> image::RgbImage {
    let mut raw = vec![0u8; width * height * 3];
    for (i, px) in raw.chunks_exact_mut(3).enumerate() {
        let mut acc = [0f32; 3];
        for (k, w) in weights.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            for c in 0..3 {
                acc[c] += w[i] * color[c] as f32;
            }
        }
        for c in 0..3 {
            px[c] = round_to_u8(acc[c]);
        }
    }
    image::RgbImage::from_raw(width as u32, height as u32, raw).expect("size matches")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantised_masks_sum_to_255_and_stay_close() {
        let w1 = Plane::from_vec(3, 1, vec![1.0 / 3.0, 0.0, 0.5]);
        let w2 = Plane::from_vec(3, 1, vec![1.0 / 3.0, 0.0, 0.25]);
        let bg = Plane::from_vec(3, 1, vec![1.0 / 3.0, 1.0, 0.25]);
        let q = quantise_weights(&[w1.clone(), w2.clone()], &bg);
        for i in 0..3 {
            let total = q.background[i] as u32 + q.masks[0][i] as u32 + q.masks[1][i] as u32;
            assert_eq!(total, 255);
            assert_eq!(q.roi[i] as u32, q.masks[0][i] as u32 + q.masks[1][i] as u32);
            for (plane, mask) in [(&w1, &q.masks[0]), (&w2, &q.masks[1]), (&bg, &q.background)] {
                assert!((plane.data[i] * 255.0 - mask[i] as f32).abs() < 1.0);
            }
        }
        // 85 + 85 + 85 = 255 exactly. 127.5 + 63.75 + 63.75 floors to 253; the
        // two missing units go to the largest remainders (the two .75s).
        assert_eq!(
            (q.masks[0][0], q.masks[1][0], q.background[0]),
            (85, 85, 85)
        );
        assert_eq!(
            (q.masks[0][2], q.masks[1][2], q.background[2]),
            (127, 64, 64)
        );
    }

    #[test]
    fn colorize_mixes_palette_colours() {
        let a = [1.0f32, 0.5, 0.0];
        let b = [0.0f32, 0.5, 0.0];
        let img = colorize(3, 1, &[&a, &b]);
        assert_eq!(img.get_pixel(0, 0).0, PALETTE[0]);
        let mix: Vec<u8> = (0..3)
            .map(|c| ((PALETTE[0][c] as f32 + PALETTE[1][c] as f32) / 2.0).round() as u8)
            .collect();
        assert_eq!(img.get_pixel(1, 0).0.to_vec(), mix);
        assert_eq!(img.get_pixel(2, 0).0, [0, 0, 0]);
    }
}
