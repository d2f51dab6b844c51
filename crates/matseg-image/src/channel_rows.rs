//! Windows of a pyramid made on demand: any run of any row of the R, G or B
//! plane ([`WindowRows`]) or of one channel ([`ChannelRows`], with the
//! window's exact maximum found without making every pixel), with the same
//! values as the whole window. For consumers that read a few blocks of a
//! scene-sized window (a shading or a stretched texture, where a material
//! that covers a tenth of the scene is visible).

use crate::bilinear::blend_rows;
use crate::channel::Channel;
use crate::levels::ChannelWindow;
use crate::resample::{Placement, Pyramid, WindowReader};

/// The R, G and B planes of a window, read run by run.
pub struct WindowRows<'a> {
    reader: WindowReader<'a>,
    /// Scratch: a row blend.
    blended: Vec<i16>,
}

impl<'a> WindowRows<'a> {
    /// The `w x h` window `placement` selects from `pyramid`.
    pub fn new(pyramid: &'a Pyramid, placement: &Placement, w: usize, h: usize) -> Self {
        Self {
            reader: pyramid.window(placement, w, h),
            blended: Vec::new(),
        }
    }

    /// Writes columns `x0..x0 + out.len()` of row `y` of plane `lane` (0 =
    /// R, 1 = G, 2 = B), as [`Pyramid::sample_planes`] has them.
    pub fn run(&mut self, lane: usize, y: usize, x0: usize, out: &mut [u8]) {
        self.reader.run(lane, y, x0, out, &mut self.blended);
    }
}

/// A channel window read row run by row run; see the module documentation.
pub struct ChannelRows<'a> {
    width: usize,
    height: usize,
    source: Source<'a>,
}

enum Source<'a> {
    /// Hue and saturation: the source gives no bound on them, so the window
    /// is made whole.
    Whole(ChannelWindow),
    /// R, G or B (one lane), or V (the largest of the three), resampled
    /// run by run; `lane` holds one lane's run of V.
    OnDemand {
        rows: WindowRows<'a>,
        lanes: &'static [usize],
        lane: Vec<u8>,
    },
}

impl<'a> ChannelRows<'a> {
    /// `channel` of the `w x h` window `placement` selects from `pyramid`.
    pub fn new(
        pyramid: &'a Pyramid,
        placement: &Placement,
        w: usize,
        h: usize,
        channel: Channel,
    ) -> Self {
        let lanes: &'static [usize] = match channel {
            Channel::R => &[0],
            Channel::G => &[1],
            Channel::B => &[2],
            Channel::V => &[0, 1, 2],
            Channel::H | Channel::S => {
                return Self {
                    width: w,
                    height: h,
                    source: Source::Whole(pyramid.sample_channel(placement, w, h, channel)),
                };
            }
        };
        Self {
            width: w,
            height: h,
            source: Source::OnDemand {
                rows: WindowRows::new(pyramid, placement, w, h),
                lanes,
                lane: Vec::new(),
            },
        }
    }

    /// Writes the levels of columns `x0..x0 + out.len()` of row `y`.
    pub fn run(&mut self, y: usize, x0: usize, out: &mut [u8]) {
        match &mut self.source {
            Source::Whole(window) => {
                out.copy_from_slice(&window.levels[y * self.width + x0..][..out.len()]);
            }
            Source::OnDemand { rows, lanes, lane } => {
                rows.run(lanes[0], y, x0, out);
                for &other in &lanes[1..] {
                    lane.resize(out.len(), 0);
                    rows.run(other, y, x0, lane);
                    for (o, &l) in out.iter_mut().zip(lane.iter()) {
                        *o = (*o).max(l);
                    }
                }
            }
        }
    }

    /// The highest level in the window (0 when it is empty). A resampled
    /// level never exceeds the source pixels it blends, so each row is
    /// bounded by the largest level of the source rows it reads; rows are
    /// made in decreasing order of that bound until no other can exceed
    /// the largest level found.
    pub fn max_level(&mut self) -> u8 {
        let (w, h) = (self.width, self.height);
        let bounds = match &self.source {
            Source::Whole(window) => return window.max_level(),
            Source::OnDemand { rows, lanes, .. } => {
                if w == 0 || h == 0 {
                    return 0;
                }
                rows.reader.row_bounds(lanes)
            }
        };
        let mut order: Vec<usize> = (0..h).collect();
        order.sort_by_key(|&y| std::cmp::Reverse(bounds[y]));
        let mut row = vec![0u8; w];
        let mut best = 0;
        for y in order {
            if bounds[y] <= best {
                break;
            }
            self.run(y, 0, &mut row);
            best = best.max(row.iter().copied().max().unwrap_or(0));
        }
        best
    }
}

impl WindowReader<'_> {
    /// Columns `x0..x0 + out.len()` of row `y` of plane `lane`, as
    /// [`WindowReader::plane`] has them (rows blended first, then columns:
    /// the same integer sums as either order, so the same bytes); `blended`
    /// is scratch.
    pub(crate) fn run(
        &self,
        lane: usize,
        y: usize,
        x0: usize,
        out: &mut [u8],
        blended: &mut Vec<i16>,
    ) {
        if out.is_empty() {
            return;
        }
        match self {
            WindowReader::Crop {
                level,
                x0: left,
                y0: top,
                ..
            } => {
                let start = (y + top) * level.width + left + x0;
                out.copy_from_slice(&level.planes[lane][start..start + out.len()]);
            }
            WindowReader::Bilinear {
                level,
                first,
                span,
                taps,
                rows,
                ..
            } => {
                let (first, span) = (*first, *span);
                let src = &level.planes[lane];
                let at = |s: usize| &src[s * level.width + first..][..span];
                // The row values the columns read: from the first tap of x0
                // to one past the first tap of the last column (the value
                // past the end repeats the last one, as in a whole row).
                let lo = taps.first(x0);
                let hi = taps.first(x0 + out.len() - 1) + 1;
                let end = hi.min(span - 1) + 1;
                blended.resize(span + 1, 0);
                let tap = rows[y];
                blend_rows(
                    &at(tap.first)[lo..end],
                    &at(tap.second)[lo..end],
                    tap.weight,
                    &mut blended[lo..end],
                );
                if hi == span {
                    blended[span] = blended[span - 1];
                }
                taps.blend_range(blended, x0, out);
            }
        }
    }

    /// For each output row, the largest source level (over `lanes`) that
    /// its pixels blend: no level of the row exceeds it.
    pub(crate) fn row_bounds(&self, lanes: &[usize]) -> Vec<u8> {
        let row_max = |level: &crate::resample::Level, s: usize, x: usize, n: usize| {
            lanes
                .iter()
                .map(|&l| {
                    level.planes[l][s * level.width + x..][..n]
                        .iter()
                        .copied()
                        .max()
                })
                .max()
                .flatten()
                .unwrap_or(0)
        };
        match self {
            WindowReader::Crop {
                level,
                x0,
                y0,
                out_w,
                out_h,
            } => (0..*out_h)
                .map(|y| row_max(level, y0 + y, *x0, *out_w))
                .collect(),
            WindowReader::Bilinear {
                level,
                first,
                span,
                rows,
                ..
            } => {
                // Source rows are shared by neighbouring output rows: each
                // is measured once.
                let mut measured: Vec<Option<u8>> = vec![None; level.height];
                let mut source =
                    |s: usize| *measured[s].get_or_insert_with(|| row_max(level, s, *first, *span));
                rows.iter()
                    .map(|tap| source(tap.first).max(source(tap.second)))
                    .collect()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::RgbImage;

    /// Runs and maxima equal the whole window's, for every channel, at
    /// native scale, upscaled and downscaled (several pyramid levels).
    #[test]
    fn runs_and_maximum_equal_the_whole_window() {
        let img = RgbImage::from_fn(301, 207, |x, y| {
            image::Rgb([
                ((x * 7 + y * 3) % 256) as u8,
                ((x * y) % 199) as u8,
                ((x / 5 + y * 11) % 230) as u8,
            ])
        });
        let pyramid = Pyramid::new(img);
        let (w, h) = (120, 90);
        let placements = [
            // Native scale: a crop.
            (301, 207, 40, 30),
            // Upscaled 1.7x, with the crop at the far edges.
            (512, 352, 392, 262),
            // Downscaled 2.2x (reads the first halved level).
            (137, 94, 7, 2),
        ];
        for (resized_w, resized_h, x0, y0) in placements {
            let placement = Placement {
                resized_w,
                resized_h,
                x0,
                y0,
            };
            for channel in Channel::RGB.into_iter().chain(Channel::HSV) {
                let whole = pyramid.sample_channel(&placement, w, h, channel);
                let mut rows = ChannelRows::new(&pyramid, &placement, w, h, channel);
                assert_eq!(
                    rows.max_level(),
                    whole.max_level(),
                    "{channel:?} {placement:?}"
                );
                for y in [0, 1, 44, h - 1] {
                    for (x0, len) in [(0, w), (16, 32), (w - 17, 17), (5, 1)] {
                        let mut run = vec![0u8; len];
                        rows.run(y, x0, &mut run);
                        let want = &whole.levels[y * w + x0..][..len];
                        assert_eq!(run, want, "{channel:?} {placement:?} row {y} from {x0}");
                    }
                }
            }
        }
    }

    /// A window whose largest source pixel falls between output pixels:
    /// the maximum is the largest level actually made, not the source's.
    #[test]
    fn maximum_is_the_resampled_windows_not_the_sources() {
        let mut img = RgbImage::from_pixel(40, 40, image::Rgb([10, 10, 10]));
        img.put_pixel(20, 20, image::Rgb([250, 10, 10]));
        let pyramid = Pyramid::new(img);
        let placement = Placement {
            resized_w: 70,
            resized_h: 70,
            x0: 0,
            y0: 0,
        };
        let whole = pyramid.sample_channel(&placement, 70, 70, Channel::R);
        let mut rows = ChannelRows::new(&pyramid, &placement, 70, 70, Channel::R);
        let top = rows.max_level();
        assert_eq!(top, whole.max_level());
        assert!(top < 250 && top > 10, "{top}");
    }
}
