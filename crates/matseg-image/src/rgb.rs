//! RGB on three `f32` planes (values on the 0..255 scale), as composition
//! works: hue rotation, and rounding into interleaved 8-bit RGB.

use crate::plane::round_to_u8;

/// Rounds and clamps three planes of equal length into interleaved 8-bit
/// RGB (`out` holds three values per pixel), each value as
/// [`round_to_u8`]; in explicit AVX2 when the CPU has it (16 pixels a step,
/// interleaved by byte shuffles).
pub fn interleave_rounded(planes: [&[f32]; 3], out: &mut [u8]) {
    let n = planes[0].len();
    assert!(
        planes.iter().all(|p| p.len() == n) && out.len() == 3 * n,
        "three planes of one length, three bytes a pixel"
    );
    let mut done = 0;
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present, and the lengths were checked above.
        done = unsafe { avx2::interleave_rounded(planes, out) };
    }
    let [r, g, b] = planes.map(|p| &p[done..]);
    for (((px, &r), &g), &b) in out[3 * done..].chunks_exact_mut(3).zip(r).zip(g).zip(b) {
        px.copy_from_slice(&[r, g, b].map(round_to_u8));
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use crate::bilinear::avx2::store_sixteen;
    use std::arch::x86_64::*;

    /// For each 16-byte third of 48 interleaved bytes and each channel,
    /// where each byte comes from in that channel's 16 bytes: byte `j` is
    /// pixel `j / 3`'s channel `j % 3` (-1, a zero, for the other channels).
    const SHUFFLES: [[[i8; 16]; 3]; 3] = {
        let mut masks = [[[-1i8; 16]; 3]; 3];
        let mut j = 0;
        while j < 48 {
            masks[j / 16][j % 3][j % 16] = (j / 3) as i8;
            j += 1;
        }
        masks
    };

    /// [`super::interleave_rounded`] on whole steps of 16 pixels; returns
    /// how many pixels it wrote.
    ///
    /// # Safety
    /// The CPU must have AVX2; the planes have one length, `out` three
    /// bytes per pixel.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn interleave_rounded(planes: [&[f32]; 3], out: &mut [u8]) -> usize {
        let steps = planes[0].len() / 16;
        let (half, zero, top) = (
            _mm256_set1_ps(0.5),
            _mm256_setzero_ps(),
            _mm256_set1_ps(255.0),
        );
        // As round_to_u8: add a half; `max` with zero second (a NaN gives
        // zero), then `min`, then truncate.
        let round = |p: *const f32| {
            let v = _mm256_add_ps(_mm256_loadu_ps(p), half);
            _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(v, zero), top))
        };
        let mut bytes = [[0u8; 16]; 3];
        for step in 0..steps {
            let mut channels = [_mm_setzero_si128(); 3];
            for (c, plane) in planes.iter().enumerate() {
                let at = plane.as_ptr().add(16 * step);
                store_sixteen(round(at), round(at.add(8)), bytes[c].as_mut_ptr());
                channels[c] = _mm_loadu_si128(bytes[c].as_ptr() as *const __m128i);
            }
            let dst = out.as_mut_ptr().add(48 * step) as *mut __m128i;
            for (part, masks) in SHUFFLES.iter().enumerate() {
                let mut v = _mm_setzero_si128();
                for (&channel, mask) in channels.iter().zip(masks) {
                    let mask = _mm_loadu_si128(mask.as_ptr() as *const __m128i);
                    v = _mm_or_si128(v, _mm_shuffle_epi8(channel, mask));
                }
                _mm_storeu_si128(dst.add(part), v);
            }
        }
        16 * steps
    }
}

/// Rotates the hue of every pixel of three planes of equal length by
/// `degrees` (see [`rotate_hue`]) in one vectorised loop, also compiled for
/// AVX2 and picked at run time; each pixel gets the same value wherever it
/// lies in the planes.
#[multiversion::multiversion(targets("x86_64+avx2+fma"))]
pub fn rotate_hue_planes(r: &mut [f32], g: &mut [f32], b: &mut [f32], degrees: f32) {
    for ((r, g), b) in r.iter_mut().zip(g.iter_mut()).zip(b.iter_mut()) {
        [*r, *g, *b] = rotate_hue([*r, *g, *b], degrees);
    }
}

/// Rotates the hue of an RGB (0..255) pixel by `degrees`, modulo 360°,
/// keeping its HSV saturation and value. Branch-free, so loops over many
/// pixels vectorise.
#[inline]
pub fn rotate_hue([r, g, b]: [f32; 3], degrees: f32) -> [f32; 3] {
    let max = r.max(g).max(b);
    let spread = max - r.min(g).min(b);
    let inverse = if spread > 0.0 { 1.0 / spread } else { 0.0 };
    // Hue in sextants, [0, 6).
    let from_r = (g - b) * inverse;
    let from_r = if from_r < 0.0 { from_r + 6.0 } else { from_r };
    let hue = if max == r {
        from_r
    } else if max == g {
        (b - r) * inverse + 2.0
    } else {
        (r - g) * inverse + 4.0
    };
    let turn = degrees.rem_euclid(360.0) / 60.0;
    let hue = wrap_sextants(hue + turn);
    // HSV to RGB: channel n sits at k = (n + hue) mod 6 sextants from its peak.
    let channel = |n: f32| {
        let k = wrap_sextants(n + hue);
        max - spread * k.min(4.0 - k).clamp(0.0, 1.0)
    };
    [channel(5.0), channel(3.0), channel(1.0)]
}

/// `x` in `[0, 12)` reduced modulo 6.
#[inline]
fn wrap_sextants(x: f32) -> f32 {
    if x >= 6.0 {
        x - 6.0
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f32; 3], b: [f32; 3]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-3)
    }

    #[test]
    fn hue_rotation_turns_primaries_and_wraps_modulo_360() {
        let red = [255.0, 0.0, 0.0];
        assert!(close(rotate_hue(red, 120.0), [0.0, 255.0, 0.0]));
        assert!(close(rotate_hue(red, 240.0), [0.0, 0.0, 255.0]));
        assert!(close(rotate_hue(red, 480.0), [0.0, 255.0, 0.0]));
        assert!(close(rotate_hue(red, -120.0), [0.0, 0.0, 255.0]));
        assert!(close(rotate_hue(red, 360.0), red));
        assert!(close(rotate_hue(red, 60.0), [255.0, 255.0, 0.0]));
        let grey = [90.0, 90.0, 90.0];
        assert!(close(rotate_hue(grey, 77.0), grey));
    }

    #[test]
    fn hue_rotation_keeps_value_and_saturation_and_composes() {
        for px in [[12.0, 200.0, 99.0], [250.0, 3.0, 40.0], [7.0, 70.0, 7.5]] {
            let turned = rotate_hue(px, 100.0);
            let max = |p: [f32; 3]| p[0].max(p[1]).max(p[2]);
            let min = |p: [f32; 3]| p[0].min(p[1]).min(p[2]);
            assert!((max(turned) - max(px)).abs() < 1e-3);
            assert!((min(turned) - min(px)).abs() < 1e-3);
            assert!(close(rotate_hue(turned, 260.0), px), "{px:?}");
        }
    }

    #[test]
    fn planes_interleave_and_rotate_like_pixels() {
        let [mut r, mut g, mut b] = [
            vec![255.0f32, 12.0, 0.0],
            vec![0.0, 200.0, 7.0],
            vec![0.0, 99.0, 7.0],
        ];
        let mut raw = [0u8; 9];
        interleave_rounded([&r, &g, &b], &mut raw);
        assert_eq!(raw, [255, 0, 0, 12, 200, 99, 0, 7, 7]);
        // Whole steps of 16 pixels and a tail, with values out of range,
        // halves and NaN: every byte as round_to_u8 puts it.
        let n = 16 * 5 + 7;
        let value = |i: usize| match i % 11 {
            0 => f32::NAN,
            1 => -3.0,
            2 => 300.0,
            3 => 254.5,
            _ => (i * 37 % 512) as f32 / 2.0 - 1.0,
        };
        let planes: [Vec<f32>; 3] =
            std::array::from_fn(|c| (0..n).map(|i| value(3 * i + c)).collect());
        let mut raw = vec![0u8; 3 * n];
        interleave_rounded(planes.each_ref().map(|p| p.as_slice()), &mut raw);
        let want: Vec<u8> = (0..3 * n).map(|j| round_to_u8(value(j))).collect();
        assert_eq!(raw, want);
        let before: Vec<[f32; 3]> = (0..3).map(|i| [r[i], g[i], b[i]]).collect();
        rotate_hue_planes(&mut r, &mut g, &mut b, 33.0);
        for (i, px) in before.into_iter().enumerate() {
            assert_eq!([r[i], g[i], b[i]], rotate_hue(px, 33.0));
        }
    }
}
