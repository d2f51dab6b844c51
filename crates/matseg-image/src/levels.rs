//! Windows of one channel on 8-bit levels, and their histograms: every
//! statistic a soft map needs (maximum, counts above a threshold, mass of a
//! ramp) is read off 256 bins instead of a pass over the pixels.

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
        self.levels.iter().copied().max().unwrap_or(0)
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
        look_up(&self.levels[y * self.width + x0..][..run.len()], table, run);
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
                c.add_run_by(y, 0, row, top_positive, positive);
            } else {
                c.add_run_by(y, 0, row, any_positive, positive);
            }
        }
        c
    }
}

/// `out[i] = table[levels[i]]`, over the length of `out`.
pub fn look_up(levels: &[u8], table: &LevelTable, out: &mut [f32]) {
    for (v, &l) in out.iter_mut().zip(levels) {
        *v = table[l as usize];
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

    /// All pixels.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// The highest level present (0 when there is none).
    pub fn max_level(&self) -> u8 {
        self.counts.iter().rposition(|&c| c > 0).unwrap_or(0) as u8
    }

    /// Pixels whose value (`values[level]`) is strictly above `t`.
    pub fn count_above(&self, values: &LevelTable, t: f32) -> u64 {
        self.counts
            .iter()
            .zip(values)
            .filter(|(_, &v)| v > t)
            .map(|(&c, _)| c)
            .sum()
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
        assert_eq!(hist.total(), 1001);
        for l in 0..=255u8 {
            let direct = levels.iter().filter(|&&v| v == l).count() as u64;
            assert_eq!(hist.count(l), direct, "level {l}");
        }
        assert_eq!(hist.max_level(), 252);
        assert_eq!(window(levels).max_level(), 252);
    }

    #[test]
    fn values_counts_and_sums_agree_with_the_mapped_plane() {
        let w = window(vec![0, 10, 10, 50, 200, 255, 3]);
        let hist = w.histogram();
        let full = level_values(255);
        assert_eq!(full[255], 1.0);
        assert_eq!(hist.count_above(&full, 10.0 / 255.0), 3);
        let by_max = level_values(hist.max_level());
        assert_eq!(hist.count_above(&by_max, 0.0), 6);
        let plane = w.map_levels(&full);
        assert_eq!(plane.data[4], 200.0 / 255.0);
        let mut row = vec![0.0; 7];
        w.map_run(0, 0, &full, &mut row);
        assert_eq!(row, plane.data);
        assert!((hist.weighted_sum(&full) - plane.sum()).abs() < 1e-9);
        // A black window stays black when normalised by its maximum.
        let black = window(vec![0; 5]);
        assert_eq!(level_values(black.histogram().max_level())[0], 0.0);
    }
}
