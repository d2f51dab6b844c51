//! Windows of one channel on 8-bit levels and the statistics a soft map
//! needs of them: the maximum, how many pixels are at or above a level (a
//! vectorised pass, a compare per pixel), and whole histograms (a ramp's
//! mass).

use crate::channel::Channel;
use crate::coverage::Coverage;
use crate::plane::Plane;

/// A `width x height` window of one channel, as levels 0..=255.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelWindow {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// The channel the levels are of.
    pub channel: Channel,
    /// `width * height` levels, row by row.
    pub levels: Vec<u8>,
}

/// One value per level: what each level maps to.
pub type LevelTable = [f32; 256];

impl ChannelWindow {
    /// The histogram of the levels.
    pub fn histogram(&self) -> LevelHistogram {
        LevelHistogram::of(&self.levels)
    }

    /// The highest level in the window (0 when it is empty).
    pub fn max_level(&self) -> u8 {
        highest(&self.levels)
    }

    /// The plane of `table[level]` for every pixel.
    pub fn map_levels(&self, table: &LevelTable) -> Plane {
        let data = self.levels.iter().map(|&l| table[l as usize]).collect();
        Plane::from_vec(self.width, self.height, data)
    }

    /// Columns `x0..x0 + run.len()` of row `y` of
    /// [`ChannelWindow::map_levels`], written into `run`, for callers that
    /// stream parts of rows.
    pub fn map_run(&self, y: usize, x0: usize, table: &LevelTable, run: &mut [f32]) {
        look_up(self.run(y, x0, run.len()), table, run);
    }

    /// The levels of columns `x0..x0 + n` of row `y`.
    pub fn run(&self, y: usize, x0: usize, n: usize) -> &[u8] {
        &self.levels[y * self.width + x0..][..n]
    }

    /// Where [`ChannelWindow::map_levels`] of `table` is positive. When
    /// the table never decreases (a channel through a ramp), a block is
    /// tested by comparing its levels with the first positive level.
    pub fn coverage(&self, table: &LevelTable) -> Coverage {
        let mut c = Coverage::empty(self.width, self.height);
        let Some(first) = table.iter().position(|&v| v > 0.0) else {
            return c;
        };
        let monotone = table.windows(2).all(|p| p[0] <= p[1]);
        let positive = |l: &u8| table[*l as usize] > 0.0;
        let first = first as u8;
        // An OR of comparisons vectorises (each block's maximum, reduced
        // across the register, took about half as long again).
        let top_positive = |block: &[u8]| block.iter().fold(false, |any, &l| any | (l >= first));
        let any_positive = |block: &[u8]| block.iter().any(positive);
        for (y, row) in self.levels.chunks_exact(self.width.max(1)).enumerate() {
            if monotone {
                c.add_run_by(y, 0, row, top_positive);
            } else {
                c.add_run_by(y, 0, row, any_positive);
            }
        }
        c
    }
}

/// The highest of `levels` (0 for none). A fold of maxima vectorises
/// (`Iterator::max` on bytes stayed a scalar loop of comparisons).
pub(crate) fn highest(levels: &[u8]) -> u8 {
    levels.iter().fold(0, |top, &l| top.max(l))
}

/// `out[i] = table[levels[i]]`, over the length of `out`.
pub fn look_up(levels: &[u8], table: &LevelTable, out: &mut [f32]) {
    for (v, &l) in out.iter_mut().zip(levels) {
        *v = table[l as usize];
    }
}

/// [`look_up`] of [`level_values`]`(divisor)`, computed: the same division
/// of each level, which vectorises (the table's loads do not); also
/// compiled for AVX2, picked at run time.
#[multiversion::multiversion(targets("x86_64+avx2"))]
pub fn look_up_scaled(levels: &[u8], divisor: u8, out: &mut [f32]) {
    let d = divisor.max(1) as f32;
    for (v, &l) in out.iter_mut().zip(levels) {
        *v = l as f32 / d;
    }
}

/// The level at which `table` steps from exactly 0 to exactly 1, when it is
/// such a step (the table of a binary map: pipeline.md §1.4 with `t_lo = t_hi`).
pub fn step_level(table: &LevelTable) -> Option<u8> {
    let step = table.iter().position(|&v| v == 1.0)?;
    let is_step =
        table[..step].iter().all(|&v| v == 0.0) && table[step..].iter().all(|&v| v == 1.0);
    is_step.then_some(step as u8)
}

/// [`look_up`] of a table that steps from 0 to 1 at `step`: a comparison
/// per level, which vectorises (the table's loads do not); also compiled
/// for AVX2, picked at run time.
#[multiversion::multiversion(targets("x86_64+avx2"))]
pub fn look_up_step(levels: &[u8], step: u8, out: &mut [f32]) {
    for (v, &l) in out.iter_mut().zip(levels) {
        *v = if l >= step { 1.0 } else { 0.0 };
    }
}

/// Counts of a window's pixels at or above given levels: each made once,
/// when asked for, by a pass over the window; those made so far bound every
/// other (the count never grows with the level), which settles most
/// threshold tests without a pass.
#[derive(Clone, Debug)]
pub struct LevelCounts<'w> {
    window: &'w ChannelWindow,
    /// `known[l]`: the count at or above level `l`, once made; 256 stands
    /// for "above every level" (always 0).
    known: [Option<u64>; 257],
}

impl<'w> LevelCounts<'w> {
    /// The past-the-top level: no pixel is at or above it.
    pub const PAST_TOP: usize = 256;

    /// No counts made yet of `window` but the two ends.
    pub fn new(window: &'w ChannelWindow) -> Self {
        let mut known = [None; 257];
        known[0] = Some(window.levels.len() as u64);
        known[Self::PAST_TOP] = Some(0);
        Self { window, known }
    }

    /// The first level whose value (`values[level]`) is strictly above
    /// `t`, or [`LevelCounts::PAST_TOP`]: for a table that never decreases,
    /// the pixels above `t` are those at or above it.
    ///
    /// # Panics
    /// In debug builds, when `values` decreases somewhere.
    pub fn first_above(values: &LevelTable, t: f32) -> usize {
        debug_assert!(
            values.windows(2).all(|p| p[0] <= p[1]),
            "values never decrease"
        );
        values.iter().position(|&v| v > t).unwrap_or(Self::PAST_TOP)
    }

    /// The least and the most the count at or above `level` (0..=256) can
    /// be, from the counts made so far (equal once it is made).
    pub fn bounds(&self, level: usize) -> (u64, u64) {
        let most = self.known[..=level].iter().rev().find_map(|&c| c);
        let least = self.known[level..].iter().find_map(|&c| c);
        (least.unwrap_or(0), most.unwrap_or(0))
    }

    /// The count at or above `level` (0..=256), made now if it is not yet.
    pub fn exact(&mut self, level: usize) -> u64 {
        *self.known[level].get_or_insert_with(|| count_at_least(&self.window.levels, level as u8))
    }
}

/// How many of `levels` are `level` or above; in explicit AVX2 when the CPU
/// has it (a compare and a subtract per 32 levels).
fn count_at_least(levels: &[u8], level: u8) -> u64 {
    let mut done = 0;
    let mut count = 0;
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present.
        (done, count) = unsafe { avx2::count_at_least(levels, level) };
    }
    count + levels[done..].iter().filter(|&&l| l >= level).count() as u64
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    /// [`super::count_at_least`] on whole steps of 32 levels: how many
    /// levels it read and how many of those were `level` or above.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn count_at_least(levels: &[u8], level: u8) -> (usize, u64) {
        let steps = levels.len() / 32;
        let at_least = _mm256_set1_epi8(level as i8);
        let mut sums = _mm256_setzero_si256();
        let mut step = 0;
        while step < steps {
            // Byte counters gain at most one a step: summed every 255 steps,
            // before they could wrap.
            let end = steps.min(step + 255);
            let mut counters = _mm256_setzero_si256();
            for s in step..end {
                let v = _mm256_loadu_si256(levels.as_ptr().add(32 * s) as *const __m256i);
                // All ones where v >= level, i.e. where max(v, level) == v.
                let above = _mm256_cmpeq_epi8(_mm256_max_epu8(v, at_least), v);
                counters = _mm256_sub_epi8(counters, above);
            }
            sums = _mm256_add_epi64(sums, _mm256_sad_epu8(counters, _mm256_setzero_si256()));
            step = end;
        }
        let mut lanes = [0u64; 4];
        _mm256_storeu_si256(lanes.as_mut_ptr() as *mut __m256i, sums);
        (32 * steps, lanes.iter().sum())
    }
}

/// The channel's values on `[0, 1]`: `level / divisor` (`divisor` 255 for
/// the full range, or the window's top level to normalise by the maximum;
/// 0 is taken as 1, so a black window stays 0).
pub fn level_values(divisor: u8) -> LevelTable {
    let d = divisor.max(1) as f32;
    std::array::from_fn(|l| l as f32 / d)
}

/// Pixel counts per level.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LevelHistogram {
    counts: [u64; 256],
}

impl LevelHistogram {
    /// Counts the levels. Four interleaved sub-histograms keep runs of equal
    /// levels (common in maps) from waiting on the same counter.
    pub fn of(levels: &[u8]) -> Self {
        let mut sub = [[0u32; 256]; 4];
        let mut chunks = levels.chunks_exact(4);
        for c in &mut chunks {
            sub[0][c[0] as usize] += 1;
            sub[1][c[1] as usize] += 1;
            sub[2][c[2] as usize] += 1;
            sub[3][c[3] as usize] += 1;
        }
        for &l in chunks.remainder() {
            sub[0][l as usize] += 1;
        }
        let counts = std::array::from_fn(|l| sub.iter().map(|s| s[l] as u64).sum());
        Self { counts }
    }

    /// The count of pixels at `level`.
    pub fn count(&self, level: u8) -> u64 {
        self.counts[level as usize]
    }

    /// The sum over pixels of `table[level]`, in `f64`.
    pub fn weighted_sum(&self, table: &LevelTable) -> f64 {
        self.counts
            .iter()
            .zip(table)
            .map(|(&c, &v)| c as f64 * v as f64)
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn window(levels: Vec<u8>) -> ChannelWindow {
        ChannelWindow {
            width: levels.len(),
            height: 1,
            channel: Channel::R,
            levels,
        }
    }

    #[test]
    fn histogram_counts_match_a_direct_count() {
        let levels: Vec<u8> = (0..1001u32).map(|i| ((i * i * 7) % 253) as u8).collect();
        let hist = window(levels.clone()).histogram();
        for l in 0..=255u8 {
            let direct = levels.iter().filter(|&&v| v == l).count() as u64;
            assert_eq!(hist.count(l), direct, "level {l}");
        }
        assert_eq!(window(levels).max_level(), 252);
    }

    /// Every level of the whole range, in a window longer than one group
    /// of byte counters (255 steps of 32) and not a whole number of steps.
    #[test]
    fn counts_at_or_above_a_level_match_a_direct_count() {
        let levels: Vec<u8> = (0..20_011u32)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
            .collect();
        for level in [0u8, 1, 2, 77, 128, 200, 254, 255] {
            let direct = levels.iter().filter(|&&l| l >= level).count() as u64;
            assert_eq!(count_at_least(&levels, level), direct, "level {level}");
            assert_eq!(count_at_least(&levels[..31], level), {
                levels[..31].iter().filter(|&&l| l >= level).count() as u64
            });
        }
        // All 255s: every byte counter reaches its limit and must not wrap.
        assert_eq!(count_at_least(&[255; 8160 * 2 + 5], 255), 8160 * 2 + 5);
    }

    #[test]
    fn level_counts_are_exact_and_bound_the_counts_not_made() {
        let levels: Vec<u8> = (0..5_000u32).map(|i| ((i * 37) % 211) as u8).collect();
        let w = window(levels.clone());
        let direct = |level: usize| levels.iter().filter(|&&l| l as usize >= level).count() as u64;
        let mut counts = LevelCounts::new(&w);
        assert_eq!(counts.bounds(0), (5_000, 5_000));
        assert_eq!(counts.bounds(LevelCounts::PAST_TOP), (0, 0));
        assert_eq!(counts.bounds(100), (0, 5_000));
        for made in [150, 60, 61, 200] {
            assert_eq!(counts.exact(made), direct(made));
            for level in 0..=LevelCounts::PAST_TOP {
                let (least, most) = counts.bounds(level);
                assert!(
                    least <= direct(level) && direct(level) <= most,
                    "level {level}"
                );
            }
        }
        assert_eq!(counts.bounds(60), (direct(60), direct(60)));
        assert_eq!(counts.bounds(100), (direct(150), direct(61)));
        // Values above a threshold are the levels from the first above it.
        let full = level_values(255);
        assert_eq!(LevelCounts::first_above(&full, 10.0 / 255.0), 11);
        assert_eq!(LevelCounts::first_above(&full, 1.0), LevelCounts::PAST_TOP);
        assert_eq!(LevelCounts::first_above(&level_values(50), 0.5), 26);
    }

    /// Levels divided as a computation equal [`level_values`]' table, for
    /// every divisor and level, on runs longer and shorter than a vector.
    #[test]
    fn scaled_levels_equal_the_value_table() {
        let levels: Vec<u8> = (0..=255).collect();
        for divisor in 0..=255u8 {
            let table = level_values(divisor);
            for n in [3, 8, 256] {
                let (mut want, mut got) = (vec![0.0; n], vec![-1.0; n]);
                look_up(&levels[256 - n..], &table, &mut want);
                look_up_scaled(&levels[256 - n..], divisor, &mut got);
                assert_eq!(got, want, "divisor {divisor}, {n} levels");
            }
        }
    }

    /// Step tables are found (and only they), and looking one up by
    /// comparison gives the table's values, on runs longer and shorter than
    /// a vector.
    #[test]
    fn step_tables_look_up_by_comparison() {
        let full = level_values(255);
        let binary = |t: f32| full.map(|v| f32::from(u8::from(v > t)));
        assert_eq!(step_level(&binary(0.5)), Some(128));
        assert_eq!(step_level(&binary(-1.0)), Some(0));
        assert_eq!(step_level(&binary(1.0)), None, "all zeros");
        let ramp = full.map(|v| ((v - 0.2) / 0.3).clamp(0.0, 1.0));
        assert_eq!(step_level(&ramp), None);
        let mut spike = binary(0.5);
        spike[200] = 0.0;
        assert_eq!(step_level(&spike), None);
        let levels: Vec<u8> = (0..77u32).map(|i| (i * 97 % 256) as u8).collect();
        for t in [0.1, 0.5, 0.99] {
            let table = binary(t);
            let step = step_level(&table).unwrap();
            for n in [1, 7, 8, 33, 77] {
                let (mut want, mut got) = (vec![0.0; n], vec![-1.0; n]);
                look_up(&levels[..n], &table, &mut want);
                look_up_step(&levels[..n], step, &mut got);
                assert_eq!(got, want, "threshold {t}, {n} levels");
            }
        }
    }

    #[test]
    fn values_and_sums_agree_with_the_mapped_plane() {
        let w = window(vec![0, 10, 10, 50, 200, 255, 3]);
        let full = level_values(255);
        assert_eq!(full[255], 1.0);
        let plane = w.map_levels(&full);
        assert_eq!(plane.data[4], 200.0 / 255.0);
        let mut row = vec![0.0; 7];
        w.map_run(0, 0, &full, &mut row);
        assert_eq!(row, plane.data);
        assert!((w.histogram().weighted_sum(&full) - plane.sum()).abs() < 1e-9);
        // A black window stays black when normalised by its maximum.
        let black = window(vec![0; 5]);
        assert_eq!(level_values(black.max_level())[0], 0.0);
    }
}
