//! Annotations as written to disk: weights quantised to 8 bits so that masks
//! and background sum to exactly 255, and colour previews.

use matseg_image::plane::round_to_u8;
use matseg_image::{Plane, SparsePlane};

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

/// Quantises weights to 8 bits by cumulative rounding: mask k is
/// `round(C_k) - round(C_(k-1))`, where `C_k` is 255 times the sum of the
/// first k weights, and the background takes the rest. Per pixel, background
/// plus masks sum to exactly 255, each value is within 1 of `255 * weight`,
/// and a weight of exactly 0 or 1 gives exactly 0 or 255. Each weight is
/// read on its stored runs only (adding its zeros elsewhere would change
/// nothing), each run in one pass that vectorises.
pub fn quantise_weights(weights: &[SparsePlane], background: &Plane) -> QuantisedAnnotation {
    let (w, n) = (background.width, background.len());
    let mut cumulative = vec![0f32; n];
    let mut rounded = vec![0u8; n];
    let masks = weights
        .iter()
        .map(|weight| {
            let mut mask = vec![0u8; n];
            for y in 0..background.height {
                for (x0, run) in weight.row_runs(y) {
                    let at = y * w + x0..y * w + x0 + run.len();
                    let (c, r, m) = (
                        &mut cumulative[at.clone()],
                        &mut rounded[at.clone()],
                        &mut mask[at],
                    );
                    for (((c, r), m), &v) in c.iter_mut().zip(r).zip(m).zip(run) {
                        *c += v * 255.0;
                        let next = round_to_u8(*c);
                        // max: float sums never step back, but the quantity must not wrap.
                        *m = next.max(*r) - *r;
                        *r = next.max(*r);
                    }
                }
            }
            mask
        })
        .collect();
    QuantisedAnnotation {
        masks,
        background: rounded.iter().map(|&r| 255 - r).collect(),
        roi: rounded,
    }
}

/// Quantises a render's annotation: per-material fractions and the ROI
/// (row-major, `width x height`), the background being `1 - roi`.
pub fn quantise_fractions(
    width: usize,
    height: usize,
    fractions: &[Vec<f32>],
    roi: &[f32],
) -> QuantisedAnnotation {
    let weights: Vec<SparsePlane> = fractions
        .iter()
        .map(|f| SparsePlane::dense(Plane::from_vec(width, height, f.clone())))
        .collect();
    let background = Plane::from_vec(width, height, roi.iter().map(|r| 1.0 - r).collect());
    quantise_weights(&weights, &background)
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
pub fn colourise(width: usize, height: usize, weights: &[&[f32]]) -> image::RgbImage {
    let mut raw = vec![0u8; width * height * 3];
    for (i, px) in raw.chunks_exact_mut(3).enumerate() {
        let mut acc = [0f32; 3];
        for (k, w) in weights.iter().enumerate() {
            let colour = PALETTE[k % PALETTE.len()];
            for c in 0..3 {
                acc[c] += w[i] * colour[c] as f32;
            }
        }
        for c in 0..3 {
            px[c] = round_to_u8(acc[c]);
        }
    }
    image::RgbImage::from_raw(width as u32, height as u32, raw).expect("size matches")
}

/// Blends an annotation `colour` over an image `pixel`, two parts colour to
/// one part image: how every overlay of labels or soft masks on a photo
/// is drawn.
pub fn blend_annotation_colour(pixel: &mut [u8; 3], colour: [u8; 3]) {
    for (v, colour) in pixel.iter_mut().zip(colour) {
        *v = ((*v as u16 + 2 * colour as u16) / 3) as u8;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn annotation_colour_takes_two_parts_in_three() {
        let mut pixel = [0, 255, 30];
        blend_annotation_colour(&mut pixel, [255, 0, 30]);
        assert_eq!(pixel, [170, 85, 30]);
    }

    #[test]
    fn quantised_masks_sum_to_255_and_stay_close() {
        let w1 = Plane::from_vec(3, 1, vec![1.0 / 3.0, 0.0, 0.5]);
        let w2 = Plane::from_vec(3, 1, vec![1.0 / 3.0, 0.0, 0.25]);
        let bg = Plane::from_vec(3, 1, vec![1.0 / 3.0, 1.0, 0.25]);
        let dense = [w1.clone(), w2.clone()].map(SparsePlane::dense);
        let q = quantise_weights(&dense, &bg);
        for i in 0..3 {
            let total = q.background[i] as u32 + q.masks[0][i] as u32 + q.masks[1][i] as u32;
            assert_eq!(total, 255);
            assert_eq!(q.roi[i] as u32, q.masks[0][i] as u32 + q.masks[1][i] as u32);
            for (plane, mask) in [(&w1, &q.masks[0]), (&w2, &q.masks[1]), (&bg, &q.background)] {
                assert!((plane.data[i] * 255.0 - mask[i] as f32).abs() < 1.0);
            }
        }
        // 85 + 85 + 85 = 255 exactly. 127.5 rounds up to 128; 191.25 to 191,
        // so the second mask gets 63 and the background 64.
        assert_eq!(
            (q.masks[0][0], q.masks[1][0], q.background[0]),
            (85, 85, 85)
        );
        assert_eq!(
            (q.masks[0][2], q.masks[1][2], q.background[2]),
            (128, 63, 64)
        );
        assert_eq!((q.masks[0][1], q.masks[1][1], q.background[1]), (0, 0, 255));
    }

    #[test]
    fn weights_stored_on_their_blocks_quantise_as_whole_planes() {
        use matseg_image::coverage::BLOCK;
        use matseg_image::Coverage;
        // Three weights, each positive on its own blocks, overlapping.
        let (w, h) = (5 * BLOCK + 3, 4);
        let mut planes = vec![Plane::new(w, h, 0.0); 3];
        for (k, p) in planes.iter_mut().enumerate() {
            for (i, v) in p.data.iter_mut().enumerate() {
                let (x, y) = (i % w, i / w);
                if !(x / BLOCK + y + k).is_multiple_of(3) {
                    *v = ((i * 7 + k * 13) % 17) as f32 / 51.0;
                }
            }
        }
        let mut bg = Plane::new(w, h, 1.0);
        for p in &planes {
            bg.data.iter_mut().zip(&p.data).for_each(|(b, v)| *b -= v);
        }
        let sparse: Vec<SparsePlane> = planes
            .iter()
            .map(|p| {
                let mut s = SparsePlane::zeros(Coverage::of(p));
                for y in 0..h {
                    for (x0, run) in s.row_runs_mut(y) {
                        run.copy_from_slice(&p.data[y * w + x0..][..run.len()]);
                    }
                }
                s
            })
            .collect();
        let whole = planes
            .into_iter()
            .map(SparsePlane::dense)
            .collect::<Vec<_>>();
        assert!(
            sparse[0].stored() != whole[0].stored(),
            "some blocks left out"
        );
        assert_eq!(
            quantise_weights(&sparse, &bg),
            quantise_weights(&whole, &bg)
        );
    }

    #[test]
    fn colourise_mixes_palette_colours() {
        let a = [1.0f32, 0.5, 0.0];
        let b = [0.0f32, 0.5, 0.0];
        let img = colourise(3, 1, &[&a, &b]);
        assert_eq!(img.get_pixel(0, 0).0, PALETTE[0]);
        let mix: Vec<u8> = (0..3)
            .map(|c| ((PALETTE[0][c] as f32 + PALETTE[1][c] as f32) / 2.0).round() as u8)
            .collect();
        assert_eq!(img.get_pixel(1, 0).0.to_vec(), mix);
        assert_eq!(img.get_pixel(2, 0).0, [0, 0, 0]);
    }
}
