//! A selection's uncertain pixels decided with the photo's own colours
//! (as GrabCut's colour models do): the colours of the pixels the
//! selection is sure of, in and out, make two histograms, and each pixel's
//! log ratio of the two is added to the selection's own evidence. Thin
//! structures the descriptors' coarse grid blurs (grout between tiles,
//! twigs, a display's rim) take the colour of their side.

use image::RgbImage;
use rayon::prelude::*;

/// Levels per colour channel of the histograms (16: 4096 bins).
const LEVELS: usize = 16;

/// The number of colour bins.
pub const BINS: usize = LEVELS * LEVELS * LEVELS;

/// How sure a pixel's strength must be (this far from 0 or 1) to lend its
/// colour to a histogram.
const SURE: f32 = 0.25;

/// The weight of the selection's strength against the colours' log ratio:
/// a pixel of strength `s` has evidence `STRENGTH * (s - 0.5)`.
const STRENGTH: f32 = 8.0;

/// The weight of the colours' log ratio.
const COLOUR: f32 = 0.5;

/// A photo's pixels as colour bins, ready to decide any number of
/// selections.
pub struct ColourBins {
    bins: Vec<u16>,
}

impl ColourBins {
    /// `photo`'s pixels, each as its colour's bin.
    pub fn new(photo: &RgbImage) -> Self {
        let step = (256 / LEVELS) as u8;
        let bins = photo
            .as_raw()
            .par_chunks(3)
            .map(|p| {
                let [r, g, b] = [p[0] / step, p[1] / step, p[2] / step].map(|v| v as usize);
                ((r * LEVELS + g) * LEVELS + b) as u16
            })
            .collect();
        Self { bins }
    }

    /// Each pixel's bin, row by row.
    pub fn bins(&self) -> &[u16] {
        &self.bins
    }

    /// Whether each pixel is selected, from its strength in `strength`
    /// (0..1, the photo's size) and its colour's likelihood in and out.
    pub fn decide(&self, strength: &[f32]) -> Vec<bool> {
        // The sure pixels' colours, in and out, counted in one pass.
        let counts = self
            .bins
            .par_chunks(1 << 16)
            .zip(strength.par_chunks(1 << 16))
            .fold(
                || vec![0u32; 2 * BINS],
                |mut counts, (bins, strength)| {
                    for (&bin, &s) in bins.iter().zip(strength) {
                        if s > 1.0 - SURE {
                            counts[bin as usize] += 1;
                        } else if s < SURE {
                            counts[BINS + bin as usize] += 1;
                        }
                    }
                    counts
                },
            )
            .reduce(
                || vec![0u32; 2 * BINS],
                |mut a, b| {
                    a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                    a
                },
            );
        let frequencies = |counts: &[u32]| {
            let counts: Vec<f64> = counts.iter().map(|&c| c as f64 + 1.0).collect();
            let total: f64 = counts.iter().sum();
            counts.iter().map(|c| c / total).collect::<Vec<f64>>()
        };
        let (inside, outside) = (frequencies(&counts[..BINS]), frequencies(&counts[BINS..]));
        let ratio: Vec<f32> = inside
            .iter()
            .zip(&outside)
            .map(|(i, o)| (i / o).ln() as f32)
            .collect();
        self.bins
            .par_iter()
            .zip(strength)
            .map(|(&bin, &s)| STRENGTH * (s - 0.5) + COLOUR * ratio[bin as usize] > 0.0)
            .collect()
    }
}

/// The colour in the middle of bin `bin`.
pub fn bin_colour(bin: usize) -> [u8; 3] {
    let step = 256 / LEVELS;
    let level = |l: usize| (l * step + step / 2) as u8;
    [
        level(bin / (LEVELS * LEVELS)),
        level(bin / LEVELS % LEVELS),
        level(bin % LEVELS),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_thin_line_the_strength_blurs_takes_its_colours_side() {
        // Red tiles with a grey grout line down column 10; the strength
        // says "tile" at 0.55 over the grout (blurred), sure elsewhere.
        let photo = RgbImage::from_fn(21, 8, |x, _| {
            if x == 10 {
                image::Rgb([128, 128, 128])
            } else if x < 10 {
                image::Rgb([200, 60, 40])
            } else {
                image::Rgb([128, 128, 128])
            }
        });
        let strength: Vec<f32> = (0..21 * 8)
            .map(|i| match i % 21 {
                x if x < 10 => 1.0,
                10 => 0.55,
                _ => 0.0,
            })
            .collect();
        let decided = ColourBins::new(&photo).decide(&strength);
        for y in 0..8 {
            assert!(decided[y * 21 + 3], "tile stays in");
            assert!(!decided[y * 21 + 10], "the grey line goes with the grey");
            assert!(!decided[y * 21 + 15], "outside stays out");
        }
        // A strength that is sure everywhere is kept as it is.
        let sure: Vec<f32> = (0..21 * 8).map(|i| (i % 21 < 10) as u8 as f32).collect();
        let kept = ColourBins::new(&photo).decide(&sure);
        assert!(kept.iter().zip(&sure).all(|(&k, &s)| k == (s > 0.5)));
    }

    #[test]
    fn a_bins_colour_falls_in_that_bin() {
        let photo = RgbImage::from_fn(3, 1, |x, _| {
            image::Rgb([[0, 0, 0], [17, 130, 255], [255, 255, 255]][x as usize])
        });
        let bins = ColourBins::new(&photo);
        assert_eq!(bins.bins(), &[0, (16 + 8) * 16 + 15, BINS as u16 - 1]);
        for &bin in bins.bins() {
            let again = ColourBins::new(&RgbImage::from_pixel(
                1,
                1,
                image::Rgb(bin_colour(bin as usize)),
            ));
            assert_eq!(again.bins(), &[bin]);
        }
    }
}
