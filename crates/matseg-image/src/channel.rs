//! The six image channels a soft map can be cut from, on 8-bit levels.
//!
//! The original generator works on OpenCV `uint8` images: it resizes the RGB
//! photo, converts it to HSV, and reads one channel as 0..255 levels. We do
//! the same, so every channel window is a plane of levels and everything that
//! depends on the channel's value (normalisation, thresholds, ramps) is a
//! function of at most 256 levels.

use serde::{Deserialize, Serialize};

/// One scalar property of a pixel: a colour channel or an HSV component.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Channel {
    /// Red.
    R,
    /// Green.
    G,
    /// Blue.
    B,
    /// Hue: level `l` is `l / 256` of a turn (so 256 levels cover the circle).
    H,
    /// Saturation, `255 * (max - min) / max`.
    S,
    /// Value, `max(R, G, B)`.
    V,
}

impl Channel {
    /// The RGB channels.
    pub const RGB: [Channel; 3] = [Channel::R, Channel::G, Channel::B];
    /// The HSV channels.
    pub const HSV: [Channel; 3] = [Channel::H, Channel::S, Channel::V];

    /// The channel's level (0..=255) for an 8-bit RGB pixel.
    #[inline]
    pub fn level(self, [r, g, b]: [u8; 3]) -> u8 {
        match self {
            Channel::R => r,
            Channel::G => g,
            Channel::B => b,
            Channel::H => hue_level([r, g, b]),
            Channel::S => saturation_level([r, g, b]),
            Channel::V => r.max(g).max(b),
        }
    }
}

/// Hue level of an 8-bit pixel: `round(256 * hue / 360°)` modulo 256 (0 for
/// greys). Branch-free `f32` arithmetic with one correctly rounded division,
/// so the vectorised loops of [`write_levels`] give the same levels.
#[inline]
pub fn hue_level([r, g, b]: [u8; 3]) -> u8 {
    let (r, g, b) = (r as i32, g as i32, b as i32);
    let max = r.max(g).max(b);
    let spread = max - r.min(g).min(b);
    // Numerator of the sextant position, in [-spread, 5 * spread] (0 for greys).
    let sextant = if max == r {
        g - b
    } else if max == g {
        b - r + 2 * spread
    } else {
        r - g + 4 * spread
    };
    let h = (sextant * 256) as f32 / (6 * spread.max(1)) as f32;
    // Shifted by a turn so truncation rounds; the mask wraps 256 to 0.
    ((h + 256.5) as i32 & 255) as u8
}

/// Saturation level of an 8-bit pixel: `round(255 * (max - min) / max)`, 0 for black.
#[inline]
pub fn saturation_level([r, g, b]: [u8; 3]) -> u8 {
    let max = r.max(g).max(b) as i32;
    let spread = max - r.min(g).min(b) as i32;
    ((spread * 255) as f32 / max.max(1) as f32 + 0.5) as u8
}

/// Writes the levels of `channel` for rows of R, G and B into `out` (all
/// of one length), one loop per channel so that each vectorises (AVX2 when
/// the CPU has it; hue and saturation then take explicit AVX2 code with the
/// same arithmetic, as the compiler's own vectorisation of them is slow).
pub fn write_levels(channel: Channel, [r, g, b]: [&[u8]; 3], out: &mut [u8]) {
    let n = out.len();
    let (r, g, b) = (&r[..n], &g[..n], &b[..n]);
    #[cfg(target_arch = "x86_64")]
    if matches!(channel, Channel::H | Channel::S) && std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present and the four slices have equal lengths.
        unsafe { avx2::hue_or_saturation(channel == Channel::H, r, g, b, out) };
        return;
    }
    match channel {
        Channel::R => out.copy_from_slice(r),
        Channel::G => out.copy_from_slice(g),
        Channel::B => out.copy_from_slice(b),
        Channel::H => convert_rows(r, g, b, hue_level, out),
        Channel::S => convert_rows(r, g, b, saturation_level, out),
        Channel::V => convert_rows(r, g, b, |[r, g, b]| r.max(g).max(b), out),
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{hue_level, saturation_level};
    use crate::bilinear::avx2::store_sixteen;
    use std::arch::x86_64::*;

    /// [`hue_level`] (`hue`) or [`saturation_level`] of every pixel of the
    /// planes, 16 pixels per step, with the scalar functions' arithmetic
    /// (exact integer steps, one correctly rounded `f32` division, the same
    /// rounding), so the same levels.
    ///
    /// # Safety
    /// The CPU must have AVX2, and the four slices must have equal lengths.
    #[target_feature(enable = "avx2")]
    pub unsafe fn hue_or_saturation(hue: bool, r: &[u8], g: &[u8], b: &[u8], out: &mut [u8]) {
        let n = out.len();
        let mut i = 0;
        while i + 16 <= n {
            let lo = eight(hue, r, g, b, i);
            let hi = eight(hue, r, g, b, i + 8);
            store_sixteen(lo, hi, out.as_mut_ptr().add(i));
            i += 16;
        }
        if i < n && n >= 16 {
            // The last sixteen, overlapping the step before (the same
            // levels again): runs made on demand are short, and their
            // tails would otherwise go pixel by pixel.
            let last = n - 16;
            let lo = eight(hue, r, g, b, last);
            let hi = eight(hue, r, g, b, last + 8);
            store_sixteen(lo, hi, out.as_mut_ptr().add(last));
            return;
        }
        let level = if hue { hue_level } else { saturation_level };
        for j in i..n {
            out[j] = level([r[j], g[j], b[j]]);
        }
    }

    /// The levels of pixels `i..i + 8` as `i32` lanes (each within 0..=255).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn eight(hue: bool, r: &[u8], g: &[u8], b: &[u8], i: usize) -> __m256i {
        let load =
            |p: &[u8]| _mm256_cvtepu8_epi32(_mm_loadl_epi64(p.as_ptr().add(i) as *const __m128i));
        let (r, g, b) = (load(r), load(g), load(b));
        let max = _mm256_max_epi32(_mm256_max_epi32(r, g), b);
        let spread = _mm256_sub_epi32(max, _mm256_min_epi32(_mm256_min_epi32(r, g), b));
        let one = _mm256_set1_epi32(1);
        if hue {
            // The sextant numerator: red's when max == r, else green's when
            // max == g, else blue's.
            let twice = _mm256_add_epi32(spread, spread);
            let from_r = _mm256_sub_epi32(g, b);
            let from_g = _mm256_add_epi32(_mm256_sub_epi32(b, r), twice);
            let from_b = _mm256_add_epi32(_mm256_sub_epi32(r, g), _mm256_add_epi32(twice, twice));
            let not_r = _mm256_blendv_epi8(from_b, from_g, _mm256_cmpeq_epi32(max, g));
            let sextant = _mm256_blendv_epi8(not_r, from_r, _mm256_cmpeq_epi32(max, r));
            let numerator = _mm256_cvtepi32_ps(_mm256_slli_epi32::<8>(sextant));
            let six = _mm256_mullo_epi32(_mm256_max_epi32(spread, one), _mm256_set1_epi32(6));
            let h = _mm256_div_ps(numerator, _mm256_cvtepi32_ps(six));
            let shifted = _mm256_cvttps_epi32(_mm256_add_ps(h, _mm256_set1_ps(256.5)));
            _mm256_and_si256(shifted, _mm256_set1_epi32(255))
        } else {
            let numerator = _mm256_cvtepi32_ps(_mm256_mullo_epi32(spread, _mm256_set1_epi32(255)));
            let s = _mm256_div_ps(numerator, _mm256_cvtepi32_ps(_mm256_max_epi32(max, one)));
            _mm256_cvttps_epi32(_mm256_add_ps(s, _mm256_set1_ps(0.5)))
        }
    }
}

#[multiversion::multiversion(targets("x86_64+avx2"))]
fn convert_rows(r: &[u8], g: &[u8], b: &[u8], level: impl Fn([u8; 3]) -> u8, out: &mut [u8]) {
    for (((o, &r), &g), &b) in out.iter_mut().zip(r).zip(g).zip(b) {
        *o = level([r, g, b]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Textbook hue of an RGB pixel as a fraction of a turn (reference).
    fn hue([r, g, b]: [f32; 3]) -> f32 {
        let max = r.max(g).max(b);
        let spread = max - r.min(g).min(b);
        if spread == 0.0 {
            return 0.0;
        }
        let degrees = if max == r {
            60.0 * ((g - b) / spread)
        } else if max == g {
            60.0 * ((b - r) / spread + 2.0)
        } else {
            60.0 * ((r - g) / spread + 4.0)
        };
        degrees.rem_euclid(360.0) / 360.0
    }

    /// Textbook saturation, `(max - min) / max` (reference).
    fn saturation([r, g, b]: [f32; 3]) -> f32 {
        let max = r.max(g).max(b);
        if max == 0.0 {
            0.0
        } else {
            (max - r.min(g).min(b)) / max
        }
    }

    #[test]
    fn primaries_have_the_textbook_levels() {
        let red = [255, 0, 0];
        assert_eq!(Channel::R.level(red), 255);
        assert_eq!(Channel::G.level(red), 0);
        assert_eq!(Channel::V.level(red), 255);
        assert_eq!(Channel::S.level(red), 255);
        assert_eq!(Channel::H.level(red), 0);
        // Green is a third of a turn, blue two thirds, magenta five sixths.
        assert_eq!(Channel::H.level([0, 255, 0]), 85);
        assert_eq!(Channel::H.level([0, 0, 255]), 171);
        assert_eq!(Channel::H.level([255, 0, 255]), 213);
        assert_eq!(Channel::H.level([90, 90, 90]), 0);
        assert_eq!(Channel::S.level([90, 90, 90]), 0);
        assert_eq!(Channel::S.level([0, 0, 0]), 0);
        assert_eq!(Channel::S.level([200, 50, 50]), 191);
    }

    /// The planes' levels equal the per-pixel functions on every 8-bit
    /// colour (the vectorised paths, on CPUs that have them, included).
    #[test]
    fn plane_levels_equal_the_pixel_levels_for_every_colour() {
        let g: Vec<u8> = (0..=255u8).flat_map(|g| [g; 256]).collect();
        let b: Vec<u8> = (0..256 * 256).map(|i| i as u8).collect();
        // One odd length, so that the scalar tail runs too.
        let n = g.len() - 5;
        for r in 0..=255u8 {
            let r_plane = vec![r; n];
            for channel in Channel::RGB.into_iter().chain(Channel::HSV) {
                let mut levels = vec![0u8; n];
                write_levels(channel, [&r_plane, &g, &b], &mut levels);
                for (i, &l) in levels.iter().enumerate() {
                    let want = channel.level([r, g[i], b[i]]);
                    assert_eq!(l, want, "{channel:?} of {:?}", [r, g[i], b[i]]);
                }
            }
        }
        // Short runs (as made on demand): whole steps, an overlapping last
        // step, or pixel by pixel below one step.
        let (r, g, b): (Vec<u8>, Vec<u8>, Vec<u8>) = (0..40u32)
            .map(|i| ((i * 37) as u8, (i * 101 + 7) as u8, (1000 - i * 13) as u8))
            .fold(Default::default(), |(mut r, mut g, mut b), (x, y, z)| {
                r.push(x);
                g.push(y);
                b.push(z);
                (r, g, b)
            });
        for n in 0..=40 {
            for channel in Channel::HSV {
                let mut levels = vec![0u8; n];
                write_levels(channel, [&r, &g, &b], &mut levels);
                let want: Vec<u8> = (0..n).map(|i| channel.level([r[i], g[i], b[i]])).collect();
                assert_eq!(levels, want, "{channel:?} {n}");
            }
        }
    }

    #[test]
    fn levels_round_the_exact_hue_and_saturation() {
        // Rounding to the nearest level, with f32 slack at exact halves.
        const MAX_OFF: f32 = 0.501;
        // Every 7th value of each component: about 50k colours.
        for r in (0..=255u8).step_by(7) {
            for g in (0..=255u8).step_by(7) {
                for b in (0..=255u8).step_by(7) {
                    let f = [r as f32, g as f32, b as f32];
                    let h = hue_level([r, g, b]) as f32;
                    let exact_h = hue(f) * 256.0;
                    let off = (h - exact_h).abs();
                    assert!(
                        off.min(256.0 - off) <= MAX_OFF,
                        "{r},{g},{b}: {h} vs {exact_h}"
                    );
                    let s = saturation_level([r, g, b]) as f32;
                    assert!((s - saturation(f) * 255.0).abs() <= MAX_OFF, "{r},{g},{b}");
                }
            }
        }
    }
}
