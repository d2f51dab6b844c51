//! Windows of a pyramid made on demand: any run of any row of the R, G or B
//! plane ([`WindowRows`]) or of one channel ([`ChannelRows`], with the
//! window's exact maximum found without making every pixel), with the same
//! values as the whole window. For consumers that read a few blocks of a
//! scene-sized window (a shading or a stretched texture, where a material
//! that covers a tenth of the scene is visible).

use crate::channel::{write_levels, Channel};
use crate::levels::{highest, ChannelWindow};
use crate::resample::{CropWindow, Pyramid, WindowReader};

/// The R, G and B planes of a window, read run by run.
pub struct WindowRows<'a> {
    reader: WindowReader<'a>,
    /// Scratch: a row blend.
    blended: Vec<i16>,
}

impl<'a> WindowRows<'a> {
    /// The `w x h` window `placement` selects from `pyramid`.
    pub fn new(pyramid: &'a Pyramid, placement: &CropWindow, w: usize, h: usize) -> Self {
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
    /// Scratch: the levels of a run made on demand.
    levels: Vec<u8>,
}

enum Source<'a> {
    /// Hue and saturation of a grey image: zeros, made whole.
    Whole(ChannelWindow),
    /// Hue and saturation of a colour image (boxed: its window reader
    /// holds the column taps).
    ConvertedRows(Box<ConvertedRows<'a>>),
    /// R, G or B (one lane), or V (the largest of the three), resampled
    /// run by run (boxed: its window reader holds the column taps).
    OnDemand(Box<OnDemand<'a>>),
}

/// A channel's levels made run by run from the lanes it reads: one lane's
/// run as it is, or the three lanes' runs converted.
struct OnDemand<'a> {
    rows: WindowRows<'a>,
    channel: Channel,
    lanes: &'static [usize],
    /// Scratch: a run of each of R, G and B.
    runs: [Vec<u8>; 3],
}

impl<'a> OnDemand<'a> {
    /// `channel` of the window `rows` reads, from `lanes` (all three for a
    /// channel converted from R, G and B).
    fn new(rows: WindowRows<'a>, channel: Channel, lanes: &'static [usize]) -> Self {
        Self {
            rows,
            channel,
            lanes,
            runs: Default::default(),
        }
    }

    /// The levels of columns `x0..x0 + out.len()` of row `y`.
    fn run(&mut self, y: usize, x0: usize, out: &mut [u8]) {
        if let &[lane] = self.lanes {
            self.rows.run(lane, y, x0, out);
            return;
        }
        for (lane, run) in self.runs.iter_mut().enumerate() {
            run.resize(out.len(), 0);
            self.rows.run(lane, y, x0, run);
        }
        let [r, g, b] = &self.runs;
        write_levels(self.channel, [r, g, b], out);
    }

    /// The highest level of the `w x h` window. A resampled level never
    /// exceeds the source pixels it blends, so each row is bounded by the
    /// largest level of the source rows it reads; rows are made in
    /// decreasing order of that bound until no other can exceed the largest
    /// level found. Only for R, G, B and V: hue and saturation have no
    /// such bound (see [`ConvertedRows`]).
    fn max_level(&mut self, w: usize, h: usize) -> u8 {
        if w == 0 || h == 0 {
            return 0;
        }
        let bounds = self.rows.reader.row_bounds(self.lanes);
        let mut order: Vec<usize> = (0..h).collect();
        order.sort_by_key(|&y| std::cmp::Reverse(bounds[y]));
        let mut row = vec![0u8; w];
        let mut best = 0;
        for y in order {
            if bounds[y] <= best {
                break;
            }
            self.run(y, 0, &mut row);
            best = best.max(highest(&row));
        }
        best
    }
}

/// Hue or saturation, converted from the R, G and B planes. The source
/// gives no bound on them (rounding the resampled planes can raise a dark
/// pixel's saturation by many levels), so rows are made from the top until
/// one holds the highest level there is, 255, which is then the window's
/// maximum (over the bench's scenes, two thirds of the hue windows and
/// nine tenths of the saturation ones reach it, half of those within the
/// first tenth of their rows); the rows below are made run by run as they
/// are read. A window with no 255 is made whole.
struct ConvertedRows<'a> {
    /// The rows below those made from the top.
    below: OnDemand<'a>,
    /// The levels of the rows made from the top.
    top: Vec<u8>,
    /// How many rows `top` holds.
    made: usize,
    /// The window's highest level.
    max_level: u8,
}

impl<'a> ChannelRows<'a> {
    /// `channel` of the `w x h` window `placement` selects from `pyramid`.
    pub fn new(
        pyramid: &'a Pyramid,
        placement: &CropWindow,
        w: usize,
        h: usize,
        channel: Channel,
    ) -> Self {
        let lanes = pyramid.channel_lanes(channel);
        let source = if lanes.is_none() && pyramid.is_grey() {
            Source::Whole(pyramid.sample_channel(placement, w, h, channel))
        } else {
            let rows = WindowRows::new(pyramid, placement, w, h);
            match lanes {
                Some(lanes) => Source::OnDemand(Box::new(OnDemand::new(rows, channel, lanes))),
                None => {
                    let mut top = Vec::new();
                    let made = rows.reader.converted_rows(channel, Some(u8::MAX), &mut top);
                    Source::ConvertedRows(Box::new(ConvertedRows {
                        max_level: highest(&top),
                        below: OnDemand::new(rows, channel, &[0, 1, 2]),
                        top,
                        made,
                    }))
                }
            }
        };
        Self {
            width: w,
            height: h,
            source,
            levels: Vec::new(),
        }
    }

    /// The levels of columns `x0..x0 + n` of row `y`, as the whole window
    /// has them: read in place from a window made whole, else made now.
    pub fn levels(&mut self, y: usize, x0: usize, n: usize) -> &[u8] {
        match &mut self.source {
            Source::Whole(window) => window.run(y, x0, n),
            Source::ConvertedRows(converted) => {
                if y < converted.made {
                    return &converted.top[y * self.width + x0..][..n];
                }
                self.levels.resize(n, 0);
                converted.below.run(y, x0, &mut self.levels);
                &self.levels
            }
            Source::OnDemand(on_demand) => {
                self.levels.resize(n, 0);
                on_demand.run(y, x0, &mut self.levels);
                &self.levels
            }
        }
    }

    /// The highest level in the window (0 when it is empty), found from
    /// bounds of the source where the window is made on demand.
    pub fn max_level(&mut self) -> u8 {
        match &mut self.source {
            Source::Whole(window) => window.max_level(),
            Source::ConvertedRows(converted) => converted.max_level,
            Source::OnDemand(on_demand) => on_demand.max_level(self.width, self.height),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::RgbImage;

    /// Runs and maxima equal the whole window's, for every channel, at
    /// native scale, upscaled and downscaled (several pyramid levels), of
    /// a colour image and of a grey one.
    #[test]
    fn runs_and_maximum_equal_the_whole_window() {
        let colour = RgbImage::from_fn(301, 207, |x, y| {
            image::Rgb([
                ((x * 7 + y * 3) % 256) as u8,
                ((x * y) % 199) as u8,
                ((x / 5 + y * 11) % 230) as u8,
            ])
        });
        // No channel at 0, so no saturation reaches 255: hue and saturation
        // windows are made whole, where the first image's stop early.
        let dull = RgbImage::from_fn(301, 207, |x, y| {
            image::Rgb([
                1 + ((x * 7 + y * 3) % 255) as u8,
                40 + ((x * y) % 199) as u8,
                1 + ((x / 5 + y * 11) % 230) as u8,
            ])
        });
        let grey = RgbImage::from_fn(301, 207, |x, y| image::Rgb([((x * y) % 199) as u8; 3]));
        let made = |img: RgbImage| runs_and_maximum_equal_the_whole_window_of(Pyramid::new(img));
        let (h, s) = made(colour);
        assert!(
            h.iter().all(|&rows| rows < 10) && s.iter().any(|&rows| rows < 10),
            "{h:?} {s:?}"
        );
        let (h, s) = made(dull);
        assert!(
            s.iter().all(|&rows| rows == 90) && h.iter().any(|&rows| rows < 90),
            "{h:?} {s:?}"
        );
        made(grey);
    }

    /// Checks every channel of `pyramid`'s windows; returns how many rows
    /// from the top hue and saturation windows of a colour image made
    /// whole (per placement).
    fn runs_and_maximum_equal_the_whole_window_of(pyramid: Pyramid) -> (Vec<usize>, Vec<usize>) {
        let mut made = (Vec::new(), Vec::new());
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
            let placement = CropWindow {
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
                if let Source::ConvertedRows(converted) = &rows.source {
                    match channel {
                        Channel::H => made.0.push(converted.made),
                        _ => made.1.push(converted.made),
                    }
                }
                for y in [0, 1, 44, h - 1] {
                    for (x0, len) in [(0, w), (16, 32), (w - 17, 17), (5, 1)] {
                        let want = &whole.levels[y * w + x0..][..len];
                        let run = rows.levels(y, x0, len);
                        assert_eq!(run, want, "{channel:?} {placement:?} row {y} from {x0}");
                    }
                }
            }
        }
        made
    }

    /// A window whose largest source pixel falls between output pixels:
    /// the maximum is the largest level actually made, not the source's.
    #[test]
    fn maximum_is_the_resampled_windows_not_the_sources() {
        let mut img = RgbImage::from_pixel(40, 40, image::Rgb([10, 10, 10]));
        img.put_pixel(20, 20, image::Rgb([250, 10, 10]));
        let pyramid = Pyramid::new(img);
        let placement = CropWindow {
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
