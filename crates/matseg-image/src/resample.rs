//! Resampling through a mip pyramid: "resize to W'xH', then crop a window" done
//! in one pass that only computes the output pixels.

use crate::bilinear::{blend_rows, blend_rows_rounded, ColumnTaps, ROW_SLACK, WEIGHT_ONE};
use crate::channel::{write_levels, Channel};
use crate::levels::{highest, ChannelWindow};
use image::RgbImage;
use serde::{Deserialize, Serialize};

/// Levels stop once the next one would have a side shorter than this.
const MIN_LEVEL_SIDE: usize = 32;

/// One level of a pyramid: the R, G and B planes of an 8-bit image.
#[derive(Clone, Debug)]
pub(crate) struct Level {
    width: usize,
    height: usize,
    planes: [Vec<u8>; 3],
}

impl Level {
    /// Columns `x..x + n` of row `y` of plane `lane`.
    fn row(&self, lane: usize, y: usize, x: usize, n: usize) -> &[u8] {
        &self.planes[lane][y * self.width + x..][..n]
    }

    /// [`Level::row`] and the `more` bytes that follow it in the plane
    /// (the next row's first, past the row's end), if the plane has them.
    fn row_and_more(
        &self,
        lane: usize,
        y: usize,
        x: usize,
        n: usize,
        more: usize,
    ) -> Option<&[u8]> {
        let start = y * self.width + x;
        self.planes[lane].get(start..start + n + more)
    }

    fn from_rgb8(img: &RgbImage) -> Self {
        let raw = img.as_raw();
        Self {
            width: img.width() as usize,
            height: img.height() as usize,
            planes: std::array::from_fn(|c| raw.iter().skip(c).step_by(3).copied().collect()),
        }
    }

    /// The 2x2 box average, or `None` when it would be too small.
    fn halved(&self) -> Option<Self> {
        let (w, h) = (self.width / 2, self.height / 2);
        if w.min(h) < MIN_LEVEL_SIDE {
            return None;
        }
        let planes = std::array::from_fn(|c| {
            let src = &self.planes[c];
            let mut out = Vec::with_capacity(w * h);
            for y in 0..h {
                let top = &src[2 * y * self.width..][..2 * w];
                let bottom = &src[(2 * y + 1) * self.width..][..2 * w];
                out.extend(
                    top.chunks_exact(2)
                        .zip(bottom.chunks_exact(2))
                        .map(|(t, b)| {
                            ((t[0] as u16 + t[1] as u16 + b[0] as u16 + b[1] as u16 + 2) / 4) as u8
                        }),
                );
            }
            out
        });
        Some(Self {
            width: w,
            height: h,
            planes,
        })
    }
}

/// An 8-bit RGB image and its successive 2x2 box-averaged halvings, so that
/// strong downscaling reads a level close to the target scale (no aliasing).
/// Stored as planes: sampling one channel reads only its own bytes.
#[derive(Clone, Debug)]
pub struct Pyramid {
    levels: Vec<Level>,
    /// Whether every pixel is grey (R = G = B), as a greyscale photo is:
    /// then so is every pixel of every window, resampled or not (the three
    /// planes go through the same integer arithmetic).
    grey: bool,
}

impl Pyramid {
    /// Builds the pyramid of `img` (level 0 is `img` itself).
    pub fn new(img: RgbImage) -> Self {
        Self::from_base(Level::from_rgb8(&img))
    }

    fn from_base(base: Level) -> Self {
        let [r, g, b] = &base.planes;
        let grey = r == g && g == b;
        let mut levels = vec![base];
        while let Some(next) = levels.last().and_then(Level::halved) {
            levels.push(next);
        }
        Self { levels, grey }
    }

    /// Whether every pixel is grey (R = G = B).
    pub fn is_grey(&self) -> bool {
        self.grey
    }

    /// The planes (0 = R, 1 = G, 2 = B) whose largest value at a pixel is
    /// `channel`'s level there: one for R, G and B, and for V of a grey
    /// image (its three planes are equal); three for V; `None` for H and
    /// S, which are converted from all three.
    pub(crate) fn channel_lanes(&self, channel: Channel) -> Option<&'static [usize]> {
        match channel {
            Channel::R => Some(&[0]),
            Channel::G => Some(&[1]),
            Channel::B => Some(&[2]),
            Channel::V if self.grey => Some(&[0]),
            Channel::V => Some(&[0, 1, 2]),
            Channel::H | Channel::S => None,
        }
    }

    /// The pyramid of the image turned by 90° counter-clockwise.
    pub fn quarter_turned(&self) -> Self {
        let base = &self.levels[0];
        let (w, h) = (base.height, base.width);
        let planes = base.planes.each_ref().map(|src| {
            // Output (x, y) is source (h - 1 - y, x): output rows are source
            // columns. Blocks of 32x32 keep the source rows in cache.
            const BLOCK: usize = 32;
            let mut out = vec![0u8; w * h];
            for by in (0..h).step_by(BLOCK) {
                for bx in (0..w).step_by(BLOCK) {
                    for y in by..(by + BLOCK).min(h) {
                        let column = h - 1 - y;
                        for x in bx..(bx + BLOCK).min(w) {
                            out[y * w + x] = src[x * base.width + column];
                        }
                    }
                }
            }
            out
        });
        Self::from_base(Level {
            width: w,
            height: h,
            planes,
        })
    }

    /// Width of the full-resolution image.
    pub fn width(&self) -> u32 {
        self.levels[0].width as u32
    }

    /// Height of the full-resolution image.
    pub fn height(&self) -> u32 {
        self.levels[0].height as u32
    }

    /// The R, G and B planes of the full-resolution image, row by row.
    pub fn planes(&self) -> [&[u8]; 3] {
        self.levels[0].planes.each_ref().map(|p| p.as_slice())
    }

    /// Bytes held by all levels.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| 3 * l.width * l.height).sum()
    }

    /// How to read the window `placement` selects, `out_w x out_h` pixels:
    /// worked out once and shared by every plane read from it.
    pub(crate) fn window(
        &self,
        placement: &CropWindow,
        out_w: usize,
        out_h: usize,
    ) -> WindowReader<'_> {
        let fx = self.width() as f64 / placement.resized_w as f64;
        let fy = self.height() as f64 / placement.resized_h as f64;
        if out_w == 0 || out_h == 0 || (fx == 1.0 && fy == 1.0) {
            // Native resolution: a plain crop, no interpolation.
            return WindowReader::Crop(Crop {
                level: &self.levels[0],
                x0: placement.x0 as usize,
                y0: placement.y0 as usize,
                out_w,
                out_h,
            });
        }
        // The pyramid level closest to the target scale from above.
        let shrink = fx.min(fy);
        let level = if shrink >= 2.0 {
            (shrink.log2().floor() as usize).min(self.levels.len() - 1)
        } else {
            0
        };
        let img = &self.levels[level];
        let step = (1u64 << level) as f64;
        let cols = axis_taps(out_w, placement.x0, fx / step, img.width);
        let rows = axis_taps(out_h, placement.y0, fy / step, img.height);
        let first = cols[0].first;
        let last = cols[cols.len() - 1];
        // A tap clamped at the right edge blends its column with itself,
        // which any weight leaves as it is: weighted 0, the value it reads
        // past the span (whatever lies there) adds nothing, so source rows
        // are read in place without a padded copy.
        let weight = |c: &Tap| if c.second == c.first { 0 } else { c.weight };
        WindowReader::Bilinear(Bilinear {
            level: img,
            first,
            span: last.second - first + 1,
            taps: ColumnTaps::new(cols.iter().map(|c| (c.first - first, weight(c)))),
            rows,
            out_w,
        })
    }

    /// Plane `lane` (0 = R, 1 = G, 2 = B) of the window `placement` selects.
    fn sample_plane(
        &self,
        placement: &CropWindow,
        out_w: usize,
        out_h: usize,
        lane: usize,
    ) -> Vec<u8> {
        self.window(placement, out_w, out_h).plane(lane)
    }

    /// The R, G and B rows of the selected window, made one row at a time
    /// (so that each stays in cache while it is used) and handed to
    /// `each(y, [r, g, b])` in increasing order of `y`; the same values as
    /// [`Pyramid::sample_planes`].
    pub fn sample_rows(
        &self,
        placement: &CropWindow,
        out_w: usize,
        out_h: usize,
        mut each: impl FnMut(usize, [&[u8]; 3]),
    ) {
        self.window(placement, out_w, out_h).rgb_rows(|y, rgb| {
            each(y, rgb);
            false
        });
    }

    /// The R, G and B planes of the selected window.
    pub fn sample_planes(
        &self,
        placement: &CropWindow,
        out_w: usize,
        out_h: usize,
    ) -> [Vec<u8>; 3] {
        let window = self.window(placement, out_w, out_h);
        std::array::from_fn(|lane| window.plane(lane))
    }

    /// The whole image resized to `w x h`, as an 8-bit RGB image.
    pub fn resize(&self, w: usize, h: usize) -> RgbImage {
        let whole = CropWindow {
            resized_w: w as u32,
            resized_h: h as u32,
            x0: 0,
            y0: 0,
        };
        let planes = self.sample_planes(&whole, w, h);
        let mut raw = vec![0u8; 3 * w * h];
        for (i, px) in raw.chunks_exact_mut(3).enumerate() {
            px.copy_from_slice(&planes.each_ref().map(|plane| plane[i]));
        }
        RgbImage::from_raw(w as u32, h as u32, raw).expect("buffer length matches the image size")
    }

    /// One channel of the selected window, as 8-bit levels: the RGB window
    /// is resampled first and then converted, as the original does. Of a
    /// grey image, hue and saturation are 0 and value is red, so none of
    /// them needs the three planes.
    pub fn sample_channel(
        &self,
        placement: &CropWindow,
        out_w: usize,
        out_h: usize,
        channel: Channel,
    ) -> ChannelWindow {
        let levels = match self.channel_lanes(channel) {
            Some(&[lane]) => self.sample_plane(placement, out_w, out_h, lane),
            // Grey pixels have no hue and no saturation.
            None if self.grey => vec![0u8; out_w * out_h],
            _ => {
                let mut levels = Vec::with_capacity(out_w * out_h);
                self.window(placement, out_w, out_h)
                    .converted_rows(channel, None, &mut levels);
                levels
            }
        };
        ChannelWindow {
            width: out_w,
            height: out_h,
            channel,
            levels,
        }
    }
}

/// A crop of the full-resolution level: `out_w x out_h` pixels from
/// `(x0, y0)`.
pub(crate) struct Crop<'a> {
    level: &'a Level,
    x0: usize,
    y0: usize,
    out_w: usize,
    out_h: usize,
}

impl Crop<'_> {
    /// Row `y` of plane `lane` of the crop.
    fn row(&self, lane: usize, y: usize) -> &[u8] {
        self.level.row(lane, y + self.y0, self.x0, self.out_w)
    }
}

/// Bilinear taps on one level: `taps` blend the columns `first..first +
/// span` of a row, `rows` pick and weigh the source rows.
pub(crate) struct Bilinear<'a> {
    level: &'a Level,
    first: usize,
    span: usize,
    taps: ColumnTaps,
    rows: Vec<Tap>,
    out_w: usize,
}

impl Bilinear<'_> {
    /// The columns the taps read of source row `y` of plane `lane`.
    fn source_row(&self, lane: usize, y: usize) -> &[u8] {
        self.level.row(lane, y, self.first, self.span)
    }

    /// Whether the window has more rows than the source rows it reads
    /// (then columns are blended first, once per source row).
    fn upscales(&self) -> bool {
        let source_rows = self.rows[self.rows.len() - 1].second - self.rows[0].first + 1;
        source_rows < self.rows.len()
    }
}

/// A window of a pyramid, ready to read plane by plane.
pub(crate) enum WindowReader<'a> {
    /// A crop of the full-resolution level.
    Crop(Crop<'a>),
    /// Bilinear taps on a level.
    Bilinear(Bilinear<'a>),
}

impl WindowReader<'_> {
    /// One plane of the window.
    fn plane(&self, lane: usize) -> Vec<u8> {
        let (width, height) = self.size();
        let mut out = Vec::with_capacity(width * height);
        let mut rows = PlaneRows::new(self, lane);
        for y in 0..height {
            out.extend_from_slice(rows.row(y));
        }
        out
    }

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
            WindowReader::Crop(crop) => {
                out.copy_from_slice(&crop.row(lane, y)[x0..][..out.len()]);
            }
            WindowReader::Bilinear(b) => {
                let (span, taps) = (b.span, &b.taps);
                let at = |s: usize| b.source_row(lane, s);
                // The row values the columns read: from the first tap of x0
                // to one past the first tap of the last column (a value past
                // the span is read only by a clamped tap, with weight 0).
                let lo = taps.first(x0);
                let hi = taps.first(x0 + out.len() - 1) + 1;
                let end = hi.min(span - 1) + 1;
                blended.resize(taps.padded_len(), 0);
                let tap = b.rows[y];
                blend_rows(
                    &at(tap.first)[lo..end],
                    &at(tap.second)[lo..end],
                    tap.weight,
                    &mut blended[lo..end],
                );
                taps.blend_range(blended, x0, out);
            }
        }
    }

    /// The levels of `channel` (converted from R, G and B) of the window's
    /// rows from the top, appended to `levels` row by row (the three rows
    /// stay in cache until converted) up to and including the first row
    /// that holds `stop`, or every row when none does or `stop` is `None`;
    /// returns how many rows were made.
    pub(crate) fn converted_rows(
        &self,
        channel: Channel,
        stop: Option<u8>,
        levels: &mut Vec<u8>,
    ) -> usize {
        let width = self.size().0;
        self.rgb_rows(|_, rgb| {
            let start = levels.len();
            levels.resize(start + width, 0);
            let row = &mut levels[start..];
            write_levels(channel, rgb, row);
            stop.is_some_and(|stop| row.contains(&stop))
        })
    }

    /// The R, G and B rows of the window, made one row at a time and
    /// handed to `each(y, [r, g, b])` from the top until it returns true
    /// (that row included) or the rows run out; returns how many it was
    /// handed.
    fn rgb_rows(&self, mut each: impl FnMut(usize, [&[u8]; 3]) -> bool) -> usize {
        let height = self.size().1;
        let mut lanes = [0, 1, 2].map(|lane| PlaneRows::new(self, lane));
        for y in 0..height {
            if each(y, lanes.each_mut().map(|lane| lane.row(y))) {
                return y + 1;
            }
        }
        height
    }

    /// Width and height of the window.
    fn size(&self) -> (usize, usize) {
        match self {
            WindowReader::Crop(crop) => (crop.out_w, crop.out_h),
            WindowReader::Bilinear(b) => (b.out_w, b.rows.len()),
        }
    }

    /// For each output row, the largest source level (over `lanes`) that
    /// its pixels blend: no level of the row exceeds it.
    pub(crate) fn row_bounds(&self, lanes: &[usize]) -> Vec<u8> {
        match self {
            WindowReader::Crop(crop) => (0..crop.out_h)
                .map(|y| top_level(lanes, |l| crop.row(l, y)))
                .collect(),
            WindowReader::Bilinear(b) => {
                // Source rows are shared by neighbouring output rows: each
                // is measured once.
                let mut measured: Vec<Option<u8>> = vec![None; b.level.height];
                let mut source = |s: usize| {
                    *measured[s].get_or_insert_with(|| top_level(lanes, |l| b.source_row(l, s)))
                };
                b.rows
                    .iter()
                    .map(|tap| source(tap.first).max(source(tap.second)))
                    .collect()
            }
        }
    }
}

/// One plane of a window made row by row, rows in increasing order.
///
/// Bilinear in fixed point on 8-bit pixels, rounded back to 8 bits, as
/// OpenCV resizes `uint8` images. Rows are blended first, then columns;
/// when upscaling, columns first, so each source row is blended once (the
/// same integer sums, so the same bytes; see [`crate::bilinear`]).
enum PlaneRows<'r, 'a> {
    /// A crop: its rows are read where they lie.
    Crop { crop: &'r Crop<'a>, lane: usize },
    /// Upscaling: a source row with its padding, the column blends of the
    /// two source rows last used (in slots by the rows' parity) and the
    /// output row.
    Upscale {
        b: &'r Bilinear<'a>,
        lane: usize,
        padded: Vec<u8>,
        by_columns: [Vec<i16>; 2],
        held: [usize; 2],
        out: Vec<u8>,
    },
    /// Downscaling: a row blend and the output row.
    Downscale {
        b: &'r Bilinear<'a>,
        lane: usize,
        blended: Vec<i16>,
        out: Vec<u8>,
    },
}

impl<'r, 'a> PlaneRows<'r, 'a> {
    /// Plane `lane` of the window `reader` reads.
    fn new(reader: &'r WindowReader<'a>, lane: usize) -> Self {
        match reader {
            WindowReader::Crop(crop) => PlaneRows::Crop { crop, lane },
            WindowReader::Bilinear(b) if b.upscales() => PlaneRows::Upscale {
                b,
                lane,
                padded: vec![0u8; b.span + 1 + ROW_SLACK],
                by_columns: [vec![0i16; b.out_w], vec![0i16; b.out_w]],
                held: [usize::MAX; 2],
                out: vec![0u8; b.out_w],
            },
            WindowReader::Bilinear(b) => PlaneRows::Downscale {
                b,
                lane,
                blended: vec![0i16; b.taps.padded_len()],
                out: vec![0u8; b.out_w],
            },
        }
    }

    /// Row `y`.
    fn row(&mut self, y: usize) -> &[u8] {
        // A tap clamped at the right edge reads one value past the span,
        // weighted 0 (see `Pyramid::window`): whatever lies there is fine.
        match self {
            PlaneRows::Crop { crop, lane } => crop.row(*lane, y),
            PlaneRows::Upscale {
                b,
                lane,
                padded,
                by_columns,
                held,
                out,
            } => {
                let (span, row) = (b.span, b.rows[y]);
                // Each source row's columns are blended once, into the slot
                // of its parity (output rows read source rows in increasing
                // order, two neighbours at a time); then pairs of them per
                // output row.
                for s in [row.first, row.second] {
                    if held[s % 2] != s {
                        // The source row as it lies in the plane when the
                        // plane holds the slack past its span (the loads
                        // that read it ignore it, and a tap clamped at the
                        // edge weighs the value past the span 0); else a
                        // copy followed by the slack.
                        let source =
                            match b.level.row_and_more(*lane, s, b.first, span, 1 + ROW_SLACK) {
                                Some(row) => row,
                                None => {
                                    padded[..span].copy_from_slice(b.source_row(*lane, s));
                                    &padded[..]
                                }
                            };
                        b.taps.blend_unrounded(source, &mut by_columns[s % 2]);
                        held[s % 2] = s;
                    }
                }
                let at = |s: usize| &by_columns[s % 2];
                blend_rows_rounded(at(row.first), at(row.second), row.weight, out);
                out
            }
            PlaneRows::Downscale {
                b,
                lane,
                blended,
                out,
            } => {
                let (span, row) = (b.span, b.rows[y]);
                blend_rows(
                    b.source_row(*lane, row.first),
                    b.source_row(*lane, row.second),
                    row.weight,
                    &mut blended[..span],
                );
                b.taps.blend(blended, out);
                out
            }
        }
    }
}

/// The largest level of one row over `lanes`, `row(lane)` giving the row
/// of each (0 for none).
fn top_level<'r>(lanes: &[usize], row: impl Fn(usize) -> &'r [u8]) -> u8 {
    lanes.iter().map(|&l| highest(row(l))).max().unwrap_or(0)
}

/// Two source indices along one axis and the weight of the second, in 128ths.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Tap {
    first: usize,
    second: usize,
    weight: i32,
}

/// For each output index along one axis: the two source indices and the
/// weight of the second, for a source sampled at `step` pixels per output pixel.
fn axis_taps(n: usize, offset: u32, step: f64, src_len: usize) -> Vec<Tap> {
    let last = src_len as i64 - 1;
    (0..n)
        .map(|i| {
            let u = ((i as f64 + offset as f64 + 0.5) * step - 0.5).max(0.0);
            let first = (floor_non_negative(u) as i64).min(last);
            let second = (first + 1).min(last);
            let fraction = (u - first as f64).clamp(0.0, 1.0);
            Tap {
                first: first as usize,
                second: second as usize,
                weight: round_non_negative(fraction * WEIGHT_ONE as f64) as i32,
            }
        })
        .collect()
}

/// `x.floor()` for `x >= 0` without a call into the maths library (the
/// baseline x86-64 target has no rounding instruction): truncation is the
/// floor there.
#[inline]
fn floor_non_negative(x: f64) -> u64 {
    x as u64
}

/// `x.round()` (halves away from zero) for `x >= 0`, without a call into
/// the maths library: `x - x.floor()` is exact, so comparing it with 0.5
/// decides as `round` does.
#[inline]
fn round_non_negative(x: f64) -> u64 {
    let floor = floor_non_negative(x);
    floor + u64::from(x - floor as f64 >= 0.5)
}

/// Where a scene-sized window comes from: resize the source to
/// `resized_w x resized_h`, then crop at `(x0, y0)` in resized pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct CropWindow {
    /// Width the source is resized to.
    pub resized_w: u32,
    /// Height the source is resized to.
    pub resized_h: u32,
    /// Left of the crop window, in resized pixels.
    pub x0: u32,
    /// Top of the crop window, in resized pixels.
    pub y0: u32,
}

impl CropWindow {
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

    /// The library-free floor and round agree with `f64::floor` and
    /// `f64::round` on integers, halves, their neighbours one ulp either
    /// side and a spread of other values.
    #[test]
    fn floor_and_round_without_libm_match_the_std_ones() {
        let mut values = vec![0.0, f64::MIN_POSITIVE, 0.49999999999999994, 0.5, 1.0];
        for i in 0..300u32 {
            for base in [i as f64, i as f64 + 0.5, i as f64 * 1.37, i as f64 / 7.0] {
                values.extend([base, base.next_down().max(0.0), base.next_up()]);
            }
        }
        for x in values {
            assert_eq!(floor_non_negative(x) as f64, x.floor(), "floor {x:e}");
            assert_eq!(round_non_negative(x) as f64, x.round(), "round {x:e}");
        }
    }

    /// A grey image's hue, saturation and value windows, made without its
    /// three planes, equal the conversion of the three planes resampled, at
    /// native scale, upscaled and downscaled (a halved level); one pixel of
    /// colour makes an image not grey.
    #[test]
    fn grey_images_channels_equal_the_converted_planes() {
        let img = RgbImage::from_fn(97, 83, |x, y| {
            let v = ((x * 7 + y * 13) % 256) as u8;
            image::Rgb([v, v, v])
        });
        let pyramid = Pyramid::new(img.clone());
        assert!(pyramid.is_grey());
        let (w, h) = (40, 30);
        for (resized_w, resized_h, x0, y0) in [(97, 83, 9, 40), (170, 145, 130, 2), (44, 37, 4, 7)]
        {
            let placement = CropWindow {
                resized_w,
                resized_h,
                x0,
                y0,
            };
            let [r, g, b] = pyramid.sample_planes(&placement, w, h);
            for channel in [Channel::H, Channel::S, Channel::V] {
                let mut want = vec![0u8; w * h];
                write_levels(channel, [&r, &g, &b], &mut want);
                let got = pyramid.sample_channel(&placement, w, h, channel);
                assert_eq!(got.levels, want, "{channel:?} {placement:?}");
            }
        }
        let mut tinted = img;
        tinted.put_pixel(96, 82, image::Rgb([10, 10, 11]));
        assert!(!Pyramid::new(tinted).is_grey());
    }

    #[test]
    fn identity_placement_reproduces_the_image() {
        let img = gradient(40, 30);
        let p = Pyramid::new(img.clone());
        let place = CropWindow {
            resized_w: 40,
            resized_h: 30,
            x0: 5,
            y0: 7,
        };
        let out = p.sample_planes(&place, 10, 8);
        for y in 0..8 {
            for x in 0..10 {
                let src = img.get_pixel(x as u32 + 5, y as u32 + 7);
                let got = out.each_ref().map(|plane| plane[y * 10 + x]);
                assert_eq!(got, src.0);
            }
        }
    }

    /// Upscaled windows, at the resized image's edges (where taps clamp
    /// to the last column and row) and inside it, whole and row by row,
    /// equal the fixed-point bilinear formula pixel by pixel: rows blended
    /// in 128ths, then columns, rounded once.
    #[test]
    fn upscaled_windows_equal_the_bilinear_formula_up_to_the_edges() {
        let img = RgbImage::from_fn(40, 30, |x, y| {
            image::Rgb([
                (x * 6 + y) as u8,
                (y * 8 + x * x) as u8,
                ((x * y) % 256) as u8,
            ])
        });
        let p = Pyramid::new(img.clone());
        let (rw, rh, w, h) = (67u32, 50u32, 25usize, 20usize);
        for (x0, y0) in [(rw - w as u32, rh - h as u32), (0, 0), (9, 13)] {
            let place = CropWindow {
                resized_w: rw,
                resized_h: rh,
                x0,
                y0,
            };
            let cols = axis_taps(w, x0, 40.0 / rw as f64, 40);
            let rows = axis_taps(h, y0, 30.0 / rh as f64, 30);
            let whole = p.sample_planes(&place, w, h);
            let mut by_rows = vec![[0u8; 3]; w * h];
            p.sample_rows(&place, w, h, |y, rgb| {
                for x in 0..w {
                    by_rows[y * w + x] = rgb.map(|lane| lane[x]);
                }
            });
            for (y, r) in rows.iter().enumerate() {
                for (x, c) in cols.iter().enumerate() {
                    let px = |sx: usize, sy: usize| img.get_pixel(sx as u32, sy as u32).0;
                    let want: [u8; 3] = std::array::from_fn(|lane| {
                        let blend = |sx| {
                            let (a, b) =
                                (px(sx, r.first)[lane] as i32, px(sx, r.second)[lane] as i32);
                            a * (WEIGHT_ONE - r.weight) + b * r.weight
                        };
                        let sum =
                            blend(c.first) * (WEIGHT_ONE - c.weight) + blend(c.second) * c.weight;
                        ((sum + (1 << 13)) >> 14) as u8
                    });
                    let got = whole.each_ref().map(|plane| plane[y * w + x]);
                    assert_eq!(got, want, "window at ({x0}, {y0}), pixel ({x}, {y})");
                    assert_eq!(by_rows[y * w + x], want, "row by row, pixel ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn pyramid_levels_halve_and_average() {
        let img = RgbImage::from_fn(128, 64, |x, _| image::Rgb([(x % 2) as u8 * 200, 0, 0]));
        let p = Pyramid::new(img);
        assert_eq!(p.levels.len(), 2);
        assert_eq!((p.levels[1].width, p.levels[1].height), (64, 32));
        assert!(p.levels[1].planes[0].iter().all(|&v| v == 100));
        // A 4x downscale reads the averaged level, not aliased columns.
        let out = p.resize(32, 16);
        assert!(out.pixels().all(|px| px.0 == [100, 0, 0]));
    }

    #[test]
    fn quarter_turn_matches_image_rotation() {
        let img = RgbImage::from_fn(70, 45, |x, y| image::Rgb([x as u8, y as u8, (x * y) as u8]));
        let turned = Pyramid::new(img.clone()).quarter_turned();
        let want = image::imageops::rotate270(&img);
        let (w, h) = (turned.width(), turned.height());
        assert_eq!((w, h), want.dimensions());
        assert_eq!(turned.resize(w as usize, h as usize), want);
        assert_eq!(turned.levels.len(), Pyramid::new(want).levels.len());
    }

    #[test]
    fn cover_scale_covers_the_window() {
        let s = CropWindow::cover_scale(300, 200, 600, 600);
        assert_eq!(s, 3.0);
        assert_eq!(CropWindow::resized_size(300, 200, s, 600, 600), (900, 600));
    }
}
