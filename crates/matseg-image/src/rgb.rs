//! RGB on three `f32` planes (values on the 0..255 scale), as composition
//! works: hue rotation, and rounding into interleaved 8-bit RGB.

use crate::plane::round_to_u8;

/// Rounds and clamps three planes of equal length into interleaved 8-bit
/// RGB (`out` holds three values per pixel): 64 pixels at a time, each
/// channel rounded in one vectorised loop, then interleaved; also compiled
/// for AVX2, picked at run time.
#[multiversion::multiversion(targets("x86_64+avx2"))]
pub fn interleave_rounded([r, g, b]: [&[f32]; 3], out: &mut [u8]) {
    const CHUNK: usize = 64;
    let mut bytes = [[0u8; CHUNK]; 3];
    let chunks = r.chunks(CHUNK).zip(g.chunks(CHUNK)).zip(b.chunks(CHUNK));
    for (((r, g), b), px) in chunks.zip(out.chunks_mut(3 * CHUNK)) {
        for (plane, bytes) in [r, g, b].into_iter().zip(&mut bytes) {
            for (o, &v) in bytes.iter_mut().zip(plane) {
                *o = round_to_u8(v);
            }
        }
        for (i, px) in px.chunks_exact_mut(3).enumerate() {
            px.copy_from_slice(&[bytes[0][i], bytes[1][i], bytes[2][i]]);
        }
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
        let before: Vec<[f32; 3]> = (0..3).map(|i| [r[i], g[i], b[i]]).collect();
        rotate_hue_planes(&mut r, &mut g, &mut b, 33.0);
        for (i, px) in before.into_iter().enumerate() {
            assert_eq!([r[i], g[i], b[i]], rotate_hue(px, 33.0));
        }
    }
}
