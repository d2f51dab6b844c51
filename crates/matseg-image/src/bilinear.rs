//! The two passes of fixed-point bilinear resampling on 8-bit planes: blend
//! two source rows, then blend pairs of neighbouring columns of the result.
//!
//! Weights are 128ths (7 bits), so a row blend fits `i16` and a column blend
//! of two row blends is an `i16` pair times a weight pair: one `pmaddwd`.
//! The integer arithmetic makes the AVX2 and portable paths bit-identical,
//! so a dataset does not depend on the CPU that made it.

/// Fixed-point weight of a whole source pixel: weights are 128ths.
pub const WEIGHT_ONE: i32 = 128;

/// `a * (128 - w) + b * w` for two rows of 8-bit values (at most
/// 255 * 128, so it fits `i16`), over the length of `out`. With AVX2, 16
/// values a step and one last step that overlaps the one before it (rows
/// here are often short runs, which a compiler's loop left mostly to its
/// narrow and scalar remainders).
pub fn blend_rows(a: &[u8], b: &[u8], weight: i32, out: &mut [i16]) {
    let n = out.len();
    let (a, b) = (&a[..n], &b[..n]);
    #[cfg(target_arch = "x86_64")]
    if n >= 16 && std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present, the three slices have one length of at
        // least 16.
        unsafe { avx2::blend_rows(a, b, weight, out) };
        return;
    }
    blend_rows_portable(a, b, weight, out);
}

fn blend_rows_portable(a: &[u8], b: &[u8], weight: i32, out: &mut [i16]) {
    let (keep, weight) = ((WEIGHT_ONE - weight) as i16, weight as i16);
    for ((o, &a), &b) in out.iter_mut().zip(a).zip(b) {
        *o = a as i16 * keep + b as i16 * weight;
    }
}

/// `((a * (128 - w) + b * w) + 2^13) >> 14` for two rows of column-blended
/// values (in 128ths): the second pass when columns are blended first.
/// Both orders compute the same integer sum, so they give the same bytes.
/// With AVX2, one `pmaddwd` blends eight interleaved pairs (the compiler's
/// own vectorisation widened each value and multiplied it alone).
pub fn blend_rows_rounded(a: &[i16], b: &[i16], weight: i32, out: &mut [u8]) {
    let n = out.len();
    let (a, b) = (&a[..n], &b[..n]);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present and the three slices have equal lengths.
        unsafe { avx2::blend_rows_rounded(a, b, pack_weight(weight), out) };
        return;
    }
    blend_rows_rounded_portable(a, b, weight, out);
}

fn blend_rows_rounded_portable(a: &[i16], b: &[i16], weight: i32, out: &mut [u8]) {
    let keep = WEIGHT_ONE - weight;
    for ((o, &a), &b) in out.iter_mut().zip(a).zip(b) {
        *o = ((a as i32 * keep + b as i32 * weight + (1 << 13)) >> 14) as u8;
    }
}

/// Packs the weight of a column tap as the `i16` pair `(128 - w, w)`, the
/// form the column pass multiplies with a pair of neighbouring values.
fn pack_weight(weight: i32) -> i32 {
    (weight << 16) | (WEIGHT_ONE - weight)
}

/// Blends two row-blended values by the packed weight and rounds to 8 bits.
#[inline]
fn blend_pair(a: i16, b: i16, packed: i32) -> u8 {
    let (keep, weight) = (packed & 0xFFFF, packed >> 16);
    ((a as i32 * keep + b as i32 * weight + (1 << 13)) >> 14) as u8
}

/// Values an 8-bit row given to [`ColumnTaps::blend_unrounded`] must hold
/// beyond the taps' reach (16-byte loads may read past the last tap).
pub const ROW_SLACK: usize = 16;

/// Values a row of row-blended values given to [`ColumnTaps::blend_range`]
/// must hold beyond the taps' reach (8-value loads may read past the last
/// tap).
pub const PAIR_SLACK: usize = 8;

/// The column taps of one window: for each output column, the index of the
/// first of two neighbouring row-blended values and the packed weight.
#[derive(Clone, Debug)]
pub struct ColumnTaps {
    firsts: Vec<u32>,
    packed: Vec<i32>,
    /// Length a row must have: one past the largest `first + 1`.
    row_len: usize,
    /// When every eight consecutive taps read within 16 bytes (upscaling),
    /// per group of eight: the first byte they read, and the byte shuffle
    /// that lays out their pairs as `i16`.
    narrow: Option<(Vec<u32>, Vec<[u8; 32]>)>,
    /// When every four consecutive taps (from a multiple of four) read
    /// within eight row-blended values (any scale below 2).
    narrow_pairs: Option<PairShuffles>,
}

/// Per group of eight column taps: the first row-blended value each half
/// of four reads, and the byte shuffle (per 128-bit half: of the eight
/// `i16` values from that half's first) that gives each tap's pair `(row[f],
/// row[f + 1])` as a 32-bit lane.
#[derive(Clone, Debug)]
struct PairShuffles {
    bases: Vec<[u32; 2]>,
    shuffles: Vec<[u8; 32]>,
}

/// For each complete group of eight taps, the first byte it reads and the
/// shuffle of the 16 bytes from there that gives each tap's pair `(row[f],
/// row[f + 1])` as two `i16`; `None` when some group spans more.
fn narrow_groups(firsts: &[u32]) -> Option<(Vec<u32>, Vec<[u8; 32]>)> {
    firsts
        .chunks_exact(8)
        .map(|group| {
            let base = *group.iter().min()?;
            let reach = group.iter().max()? + 1 - base;
            (reach < 16).then(|| {
                let mut shuffle = [0x80u8; 32];
                for (j, &f) in group.iter().enumerate() {
                    shuffle[4 * j] = (f - base) as u8;
                    shuffle[4 * j + 2] = (f - base + 1) as u8;
                }
                (base, shuffle)
            })
        })
        .collect::<Option<Vec<_>>>()
        .map(|groups| groups.into_iter().unzip())
}

/// The [`PairShuffles`] of every complete group of eight taps; `None` when
/// some half of a group reads more than eight values.
fn narrow_pair_groups(firsts: &[u32]) -> Option<PairShuffles> {
    firsts
        .chunks_exact(8)
        .map(|group| {
            let mut bases = [0u32; 2];
            let mut shuffle = [0u8; 32];
            for (half, taps) in group.chunks_exact(4).enumerate() {
                let base = *taps.iter().min()?;
                if taps.iter().max()? + 2 - base > 8 {
                    return None;
                }
                bases[half] = base;
                for (j, &f) in taps.iter().enumerate() {
                    let at = 2 * (f - base) as u8;
                    let lane = 16 * half + 4 * j;
                    shuffle[lane..lane + 4].copy_from_slice(&[at, at + 1, at + 2, at + 3]);
                }
            }
            Some((bases, shuffle))
        })
        .collect::<Option<Vec<_>>>()
        .map(|groups| {
            let (bases, shuffles) = groups.into_iter().unzip();
            PairShuffles { bases, shuffles }
        })
}

impl ColumnTaps {
    /// Taps from `(first, weight)` pairs, weights in 128ths.
    pub fn new(taps: impl Iterator<Item = (usize, i32)>) -> Self {
        let (firsts, packed): (Vec<u32>, Vec<i32>) =
            taps.map(|(f, w)| (f as u32, pack_weight(w))).unzip();
        let row_len = firsts.iter().map(|&f| f as usize + 2).max().unwrap_or(0);
        let narrow = narrow_groups(&firsts);
        let narrow_pairs = narrow_pair_groups(&firsts);
        Self {
            firsts,
            packed,
            row_len,
            narrow,
            narrow_pairs,
        }
    }

    /// Length a row of row-blended values given to
    /// [`ColumnTaps::blend_range`] must have.
    pub fn padded_len(&self) -> usize {
        self.row_len + PAIR_SLACK
    }

    /// `out[i] = row[first_i] * (128 - w_i) + row[first_i + 1] * w_i` for a
    /// row of 8-bit values: the first pass when columns are blended first
    /// (results in 128ths, at most 255 * 128). `row` holds [`ROW_SLACK`]
    /// values more than the taps read.
    pub fn blend_unrounded(&self, row: &[u8], out: &mut [i16]) {
        assert!(row.len() >= self.row_len + ROW_SLACK && out.len() == self.firsts.len());
        #[cfg(target_arch = "x86_64")]
        if let Some((bases, shuffles)) = &self.narrow {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 is present; every 16-byte load starts at a
                // group's first byte, at most `row_len - 2`, and `row` has
                // `ROW_SLACK` more.
                unsafe {
                    avx2::blend_columns_unrounded(
                        row,
                        (bases, shuffles),
                        &self.firsts,
                        &self.packed,
                        out,
                    )
                };
                return;
            }
        }
        blend_unrounded_portable(row, &self.firsts, &self.packed, out);
    }

    /// `out[i] = blend_pair(row[first_i], row[first_i + 1], packed_i)`.
    pub fn blend(&self, row: &[i16], out: &mut [u8]) {
        self.blend_range(row, 0, out);
    }

    /// [`ColumnTaps::blend`] for the output columns `x0..x0 + out.len()`
    /// only: it uses `row` from the first tap of `x0` to one past the
    /// first tap of the last column (`row` is [`ColumnTaps::padded_len`]
    /// long). With AVX2, whole pairs of narrow groups are blended by byte
    /// shuffles, other columns by gathers.
    pub fn blend_range(&self, row: &[i16], x0: usize, out: &mut [u8]) {
        let columns = x0..x0 + out.len();
        assert!(row.len() >= self.padded_len() && columns.end <= self.firsts.len());
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // Groups g0..g1 of eight lie whole within the columns; an even
            // number of them from g0 are shuffled.
            let (g0, g1) = (x0.div_ceil(8), columns.end / 8);
            let shuffled = match &self.narrow_pairs {
                Some(groups) if g1 > g0 + 1 => Some((groups, 8 * g0..8 * (g0 + (g1 - g0) / 2 * 2))),
                _ => None,
            };
            let (from, to) = shuffled
                .as_ref()
                .map_or((x0, x0), |(_, r)| (r.start, r.end));
            let (before, rest) = out.split_at_mut(from - x0);
            let (middle, after) = rest.split_at_mut(to - from);
            for (range, out) in [(x0..from, before), (to..columns.end, after)] {
                // SAFETY: AVX2 is present, and every index read (first,
                // first + 1) lies inside `row`, at least `row_len` long.
                unsafe {
                    avx2::blend_columns(row, &self.firsts[range.clone()], &self.packed[range], out)
                };
            }
            if let Some((PairShuffles { bases, shuffles }, range)) = shuffled {
                let groups = range.start / 8..range.end / 8;
                // SAFETY: AVX2 is present; each half loads eight values from
                // its first, at most `row_len - 2`, and `row` has
                // `PAIR_SLACK` more.
                unsafe {
                    avx2::blend_columns_narrow(
                        row,
                        (&bases[groups.clone()], &shuffles[groups]),
                        &self.packed[range],
                        middle,
                    )
                };
            }
            return;
        }
        blend_columns_portable(
            row,
            &self.firsts[columns.clone()],
            &self.packed[columns],
            out,
        );
    }

    /// The first of the two row values output column `x` reads.
    pub fn first(&self, x: usize) -> usize {
        self.firsts[x] as usize
    }
}

fn blend_unrounded_portable(row: &[u8], firsts: &[u32], packed: &[i32], out: &mut [i16]) {
    for ((o, &f), &p) in out.iter_mut().zip(firsts).zip(packed) {
        let (keep, weight) = (p & 0xFFFF, p >> 16);
        *o = (row[f as usize] as i32 * keep + row[f as usize + 1] as i32 * weight) as i16;
    }
}

fn blend_columns_portable(row: &[i16], firsts: &[u32], packed: &[i32], out: &mut [u8]) {
    for ((o, &f), &p) in out.iter_mut().zip(firsts).zip(packed) {
        *o = blend_pair(row[f as usize], row[f as usize + 1], p);
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    use std::arch::x86_64::*;

    /// Stores sixteen `i32` lanes, `lo` then `hi` (each within 0..=255),
    /// as sixteen bytes at `out`.
    ///
    /// # Safety
    /// The CPU must have AVX2, and `out` must be valid for 16 bytes.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn store_sixteen(lo: __m256i, hi: __m256i, out: *mut u8) {
        // Saturating packs work per 128-bit half; the permutes restore order.
        let words = _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_packus_epi32(lo, hi));
        let bytes = _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_packus_epi16(words, words));
        _mm_storeu_si128(out as *mut __m128i, _mm256_castsi256_si128(bytes));
    }

    /// AVX2 [`super::blend_rows`]: 16 values a step, the last step ending
    /// at the end (overlapping the one before; it writes the same values).
    ///
    /// # Safety
    /// The CPU must have AVX2; `a`, `b` and `out` have one length, at
    /// least 16.
    #[target_feature(enable = "avx2")]
    pub unsafe fn blend_rows(a: &[u8], b: &[u8], weight: i32, out: &mut [i16]) {
        let n = out.len();
        let keep = _mm256_set1_epi16((super::WEIGHT_ONE - weight) as i16);
        let weight = _mm256_set1_epi16(weight as i16);
        let mut step = |i: usize| {
            let widen = |row: &[u8]| {
                _mm256_cvtepu8_epi16(_mm_loadu_si128(row.as_ptr().add(i) as *const __m128i))
            };
            let sum = _mm256_add_epi16(
                _mm256_mullo_epi16(widen(a), keep),
                _mm256_mullo_epi16(widen(b), weight),
            );
            _mm256_storeu_si256(out.as_mut_ptr().add(i) as *mut __m256i, sum);
        };
        let mut i = 0;
        while i + 16 <= n {
            step(i);
            i += 16;
        }
        if i < n {
            step(n - 16);
        }
    }

    /// AVX2 [`super::blend_rows_rounded`] with the weight packed as by
    /// `pack_weight`: the values of the two rows are interleaved into pairs
    /// and blended by `pmaddwd`; 16 outputs per step.
    ///
    /// # Safety
    /// The CPU must have AVX2, and `a`, `b` and `out` equal lengths.
    #[target_feature(enable = "avx2")]
    pub unsafe fn blend_rows_rounded(a: &[i16], b: &[i16], packed: i32, out: &mut [u8]) {
        let n = out.len();
        let weights = _mm256_set1_epi32(packed);
        let round = _mm256_set1_epi32(1 << 13);
        let mut i = 0;
        while i + 16 <= n {
            let top = _mm256_loadu_si256(a.as_ptr().add(i) as *const __m256i);
            let bottom = _mm256_loadu_si256(b.as_ptr().add(i) as *const __m256i);
            // Per 128-bit half: pairs 0-3 and 4-7 of that half.
            let blend = |pairs: __m256i| {
                let sum = _mm256_add_epi32(_mm256_madd_epi16(pairs, weights), round);
                _mm256_srai_epi32::<14>(sum)
            };
            let lo = blend(_mm256_unpacklo_epi16(top, bottom));
            let hi = blend(_mm256_unpackhi_epi16(top, bottom));
            // Packs work per half, which keeps each half's order.
            let words = _mm256_packus_epi32(lo, hi);
            let bytes =
                _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_packus_epi16(words, words));
            _mm_storeu_si128(
                out.as_mut_ptr().add(i) as *mut __m128i,
                _mm256_castsi256_si128(bytes),
            );
            i += 16;
        }
        super::blend_rows_rounded_portable(&a[i..], &b[i..], packed >> 16, &mut out[i..]);
    }

    /// AVX2 [`super::ColumnTaps::blend`]: one 32-bit gather reads each pair of
    /// neighbours, `pmaddwd` blends it; 16 outputs per step.
    ///
    /// # Safety
    /// The CPU must have AVX2, and `first + 1 < row.len()` for every `first`.
    #[target_feature(enable = "avx2")]
    pub unsafe fn blend_columns(row: &[i16], firsts: &[u32], packed: &[i32], out: &mut [u8]) {
        let n = out.len();
        let base = row.as_ptr() as *const i32;
        let round = _mm256_set1_epi32(1 << 13);
        let mut i = 0;
        while i + 16 <= n {
            let lo = blend_eight(base, firsts, packed, i, round);
            let hi = blend_eight(base, firsts, packed, i + 8, round);
            store_sixteen(lo, hi, out.as_mut_ptr().add(i));
            i += 16;
        }
        super::blend_columns_portable(row, &firsts[i..], &packed[i..], &mut out[i..]);
    }

    /// AVX2 [`super::ColumnTaps::blend_range`] on pairs of narrow groups:
    /// each half of four outputs loads the eight row values it reads, one
    /// byte shuffle lays out the pairs, `pmaddwd` blends them; 16 outputs
    /// per step.
    ///
    /// # Safety
    /// The CPU must have AVX2; `row` holds eight values from every base;
    /// `out` is 16 outputs per two groups, `packed` one weight per output.
    #[target_feature(enable = "avx2")]
    pub unsafe fn blend_columns_narrow(
        row: &[i16],
        (bases, shuffles): (&[[u32; 2]], &[[u8; 32]]),
        packed: &[i32],
        out: &mut [u8],
    ) {
        let round = _mm256_set1_epi32(1 << 13);
        let eight = |g: usize| {
            let load = |at: u32| _mm_loadu_si128(row.as_ptr().add(at as usize) as *const __m128i);
            let [lo, hi] = bases[g];
            let values = _mm256_inserti128_si256::<1>(_mm256_castsi128_si256(load(lo)), load(hi));
            let shuffle = _mm256_loadu_si256(shuffles[g].as_ptr() as *const __m256i);
            let pairs = _mm256_shuffle_epi8(values, shuffle);
            let w = _mm256_loadu_si256(packed.as_ptr().add(8 * g) as *const __m256i);
            _mm256_srai_epi32::<14>(_mm256_add_epi32(_mm256_madd_epi16(pairs, w), round))
        };
        for step in 0..out.len() / 16 {
            store_sixteen(
                eight(2 * step),
                eight(2 * step + 1),
                out.as_mut_ptr().add(16 * step),
            );
        }
    }

    /// AVX2 [`super::ColumnTaps::blend_unrounded`] for narrow taps: each
    /// group of eight outputs loads the 16 bytes it reads into both halves
    /// of a register, one byte shuffle lays out its pairs as `i16`, and
    /// `pmaddwd` blends them; 16 outputs per step.
    ///
    /// # Safety
    /// The CPU must have AVX2, and `row` must hold 16 bytes from every base.
    #[target_feature(enable = "avx2")]
    pub unsafe fn blend_columns_unrounded(
        row: &[u8],
        (bases, shuffles): (&[u32], &[[u8; 32]]),
        firsts: &[u32],
        packed: &[i32],
        out: &mut [i16],
    ) {
        let n = out.len();
        let mut i = 0;
        while i + 16 <= n {
            let g = i / 8;
            let lo = shuffled_pairs_times_weights(row, bases[g], &shuffles[g], packed, i);
            let hi =
                shuffled_pairs_times_weights(row, bases[g + 1], &shuffles[g + 1], packed, i + 8);
            let words = _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_packs_epi32(lo, hi));
            _mm256_storeu_si256(out.as_mut_ptr().add(i) as *mut __m256i, words);
            i += 16;
        }
        super::blend_unrounded_portable(row, &firsts[i..], &packed[i..], &mut out[i..]);
    }

    /// The weighted pair sums of the eight outputs from `at` of a narrow
    /// group reading 16 bytes from `base`, as `i32`.
    ///
    /// # Safety
    /// AVX2; `row` holds 16 bytes from `base`; `at + 8 <= packed.len()`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn shuffled_pairs_times_weights(
        row: &[u8],
        base: u32,
        shuffle: &[u8; 32],
        packed: &[i32],
        at: usize,
    ) -> __m256i {
        let bytes = _mm_loadu_si128(row.as_ptr().add(base as usize) as *const __m128i);
        let shuffle = _mm256_loadu_si256(shuffle.as_ptr() as *const __m256i);
        let pairs = _mm256_shuffle_epi8(_mm256_broadcastsi128_si256(bytes), shuffle);
        let w = _mm256_loadu_si256(packed.as_ptr().add(at) as *const __m256i);
        _mm256_madd_epi16(pairs, w)
    }

    /// The weighted pair sums of outputs `at..at + 8`, as `i32`.
    ///
    /// # Safety
    /// As [`blend_columns`]; `at + 8 <= firsts.len()`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn pairs_times_weights(
        base: *const i32,
        firsts: &[u32],
        packed: &[i32],
        at: usize,
    ) -> __m256i {
        let idx = _mm256_loadu_si256(firsts.as_ptr().add(at) as *const __m256i);
        // Scale 2: the indices count i16 elements; each read takes two.
        let pairs = _mm256_i32gather_epi32::<2>(base, idx);
        let w = _mm256_loadu_si256(packed.as_ptr().add(at) as *const __m256i);
        _mm256_madd_epi16(pairs, w)
    }

    /// Outputs `at..at + 8` as `i32`, rounded and shifted back to 0..=255.
    ///
    /// # Safety
    /// As [`blend_columns`]; `at + 8 <= firsts.len()`.
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn blend_eight(
        base: *const i32,
        firsts: &[u32],
        packed: &[i32],
        at: usize,
        round: __m256i,
    ) -> __m256i {
        let sums = pairs_times_weights(base, firsts, packed, at);
        _mm256_srai_epi32::<14>(_mm256_add_epi32(sums, round))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn column_blends_match_the_portable_path_and_round() {
        let row: Vec<i16> = (0..310).map(|i| ((i * 37) % 256 * 128) as i16).collect();
        let taps = ColumnTaps::new((0..203).map(|i| (i * 7 % 298, (i % 129) as i32)));
        assert!(taps.narrow_pairs.is_none(), "scattered taps are gathered");
        let mut fast = vec![0u8; 203];
        let mut slow = vec![0u8; 203];
        taps.blend(&row, &mut fast);
        blend_columns_portable(&row, &taps.firsts, &taps.packed, &mut slow);
        assert_eq!(fast, slow);
        // Weight 0 reads the first value exactly; 128 the second; 64 the mean.
        let row = [100 * 128, 201 * 128, 0, 0, 0, 0, 0, 0, 0, 0];
        let mut out = [0u8; 3];
        ColumnTaps::new([(0, 0), (0, 128), (0, 64)].into_iter()).blend(&row, &mut out);
        assert_eq!(out, [100, 201, 151]);
    }

    #[test]
    fn columns_first_gives_the_same_bytes_as_rows_first() {
        let top: Vec<u8> = (0..40).map(|i| (i * 53 % 256) as u8).collect();
        let bottom: Vec<u8> = (0..40).map(|i| (i * 29 % 256) as u8).collect();
        let taps = ColumnTaps::new((0..30).map(|i| (i * 38 / 30, (i * 11 % 129) as i32)));
        for wy in [0, 1, 63, 64, 127, 128] {
            let mut rows = vec![0i16; 41 + PAIR_SLACK];
            blend_rows(&top, &bottom, wy, &mut rows[..40]);
            rows[40] = rows[39];
            let mut rows_first = vec![0u8; 30];
            taps.blend(&rows, &mut rows_first);

            let padded = |r: &[u8]| -> Vec<u8> {
                let mut v = r.to_vec();
                v.push(v[v.len() - 1]);
                v.resize(v.len() + ROW_SLACK, 0);
                v
            };
            let (mut ct, mut cb) = (vec![0i16; 30], vec![0i16; 30]);
            taps.blend_unrounded(&padded(&top), &mut ct);
            let mut portable = vec![0i16; 30];
            blend_unrounded_portable(&padded(&top), &taps.firsts, &taps.packed, &mut portable);
            assert_eq!(ct, portable);
            taps.blend_unrounded(&padded(&bottom), &mut cb);
            let mut cols_first = vec![0u8; 30];
            blend_rows_rounded(&ct, &cb, wy, &mut cols_first);
            assert_eq!(rows_first, cols_first, "wy {wy}");
        }
    }

    #[test]
    fn narrow_shuffled_taps_match_the_portable_path() {
        let row: Vec<u8> = (0..400).map(|i| (i * 37 % 256) as u8).collect();
        // Upscaling by 1.7 reads within 16 bytes per eight taps; a 2.5x
        // downscale does not, and takes the portable path.
        for (step, narrow) in [(1.0 / 1.7, true), (1.0, true), (2.5, false)] {
            let n = 147;
            let taps = ColumnTaps::new(
                (0..n).map(|i| ((i as f64 * step) as usize, (i * 13 % 129) as i32)),
            );
            assert_eq!(taps.narrow.is_some(), narrow, "step {step}");
            let mut fast = vec![0i16; n];
            taps.blend_unrounded(&row, &mut fast);
            let want: Vec<i16> = (0..n)
                .map(|i| {
                    let (f, w) = (taps.firsts[i] as usize, (i * 13 % 129) as i32);
                    (row[f] as i32 * (128 - w) + row[f + 1] as i32 * w) as i16
                })
                .collect();
            assert_eq!(fast, want, "step {step}");
        }
    }

    /// Column ranges starting and ending anywhere, at scales from
    /// upscaling to just below a halving (shuffled groups in the middle,
    /// gathers at the ends) and at a halving (no shuffles), equal the
    /// portable path.
    #[test]
    fn column_ranges_match_the_portable_path_at_every_offset() {
        let row: Vec<i16> = (0..700)
            .map(|i| ((i * 101) % 256 * 128 + i % 128) as i16)
            .collect();
        for (step, narrow) in [
            (1.0 / 2.3, true),
            (1.0, true),
            (1.6, true),
            (1.99, true),
            (2.5, false),
        ] {
            let n = 250;
            let taps = ColumnTaps::new(
                (0..n).map(|i| ((i as f64 * step) as usize, (i * 29 % 129) as i32)),
            );
            assert_eq!(taps.narrow_pairs.is_some(), narrow, "step {step}");
            let mut padded = row[..taps.row_len].to_vec();
            padded.resize(taps.padded_len(), -1);
            let mut want = vec![0u8; n];
            blend_columns_portable(&padded, &taps.firsts, &taps.packed, &mut want);
            for x0 in [0, 1, 5, 8, 13, 16, 40] {
                for len in [0, 1, 7, 15, 16, 17, 31, 32, 33, 64, 100, n - x0] {
                    let mut out = vec![0u8; len.min(n - x0)];
                    taps.blend_range(&padded, x0, &mut out);
                    assert_eq!(
                        out,
                        want[x0..x0 + out.len()],
                        "step {step} x0 {x0} len {len}"
                    );
                }
            }
        }
    }

    /// The row pass equals its formula for every weight, on values up to
    /// 255 * 128 and a length with a tail.
    #[test]
    fn rounded_row_blends_match_the_formula() {
        let n = 75;
        let a: Vec<i16> = (0..n).map(|i| (i * 4409 % 32641) as i16).collect();
        let b: Vec<i16> = (0..n).map(|i| (32640 - i * 977 % 32641) as i16).collect();
        for weight in 0..=WEIGHT_ONE {
            let mut fast = vec![0u8; n];
            blend_rows_rounded(&a, &b, weight, &mut fast);
            let want: Vec<u8> = (0..n)
                .map(|i| {
                    let sum = a[i] as i32 * (128 - weight) + b[i] as i32 * weight;
                    ((sum + 8192) >> 14) as u8
                })
                .collect();
            assert_eq!(fast, want, "weight {weight}");
        }
    }

    #[test]
    fn row_blends_are_exact_in_128ths() {
        let mut out = [0i16; 3];
        blend_rows(&[0, 255, 10], &[255, 255, 20], 32, &mut out);
        assert_eq!(out, [255 * 32, 255 * 128, 10 * 96 + 20 * 32]);
        // Every weight, on lengths from below one step to several with a
        // remainder (the vectorised path's overlapping last step).
        let a: Vec<u8> = (0..100u32).map(|i| (i * 89 % 256) as u8).collect();
        let b: Vec<u8> = (0..100u32).map(|i| (255 - i * 37 % 256) as u8).collect();
        for n in [1, 15, 16, 17, 31, 32, 47, 100] {
            for weight in 0..=WEIGHT_ONE {
                let mut fast = vec![0i16; n];
                blend_rows(&a, &b, weight, &mut fast);
                let want: Vec<i16> = (0..n)
                    .map(|i| (a[i] as i32 * (128 - weight) + b[i] as i32 * weight) as i16)
                    .collect();
                assert_eq!(fast, want, "n {n} weight {weight}");
            }
        }
    }
}
