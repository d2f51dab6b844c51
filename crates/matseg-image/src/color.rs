//! Colour-space helpers: RGB (0..255) to HSV (all in 0..1) and hue rotation.

/// HSV of an RGB pixel on the 0..255 scale: hue in `[0, 1)` (fraction of a turn),
/// saturation and value in `[0, 1]`.
pub fn rgb_to_hsv(rgb: [f32; 3]) -> [f32; 3] {
    [hue(rgb), saturation(rgb), value(rgb)]
}

/// Hue of an RGB (0..255) pixel as a fraction of a turn, in `[0, 1)`; 0 for greys.
#[inline]
pub fn hue(rgb: [f32; 3]) -> f32 {
    let [r, g, b] = rgb;
    let max = r.max(g).max(b);
    let delta = max - r.min(g).min(b);
    if delta <= 0.0 {
        return 0.0;
    }
    // Sextant in [0, 6), computed without a floating-point modulo.
    let sextant = if max == r {
        let h = (g - b) / delta;
        if h < 0.0 {
            h + 6.0
        } else {
            h
        }
    } else if max == g {
        (b - r) / delta + 2.0
    } else {
        (r - g) / delta + 4.0
    };
    let h = sextant / 6.0;
    if h >= 1.0 {
        h - 1.0
    } else {
        h
    }
}

/// Saturation of an RGB (0..255) pixel, `(max - min) / max`, in `[0, 1]`.
#[inline]
pub fn saturation(rgb: [f32; 3]) -> f32 {
    let max = rgb[0].max(rgb[1]).max(rgb[2]);
    if max > 0.0 {
        (max - rgb[0].min(rgb[1]).min(rgb[2])) / max
    } else {
        0.0
    }
}

/// Value of an RGB (0..255) pixel, `max / 255`, in `[0, 1]`.
#[inline]
pub fn value(rgb: [f32; 3]) -> f32 {
    rgb[0].max(rgb[1]).max(rgb[2]) / 255.0
}

/// RGB on the 0..255 scale from HSV with all components in `[0, 1]`.
pub fn hsv_to_rgb(hsv: [f32; 3]) -> [f32; 3] {
    let [h, s, v] = hsv;
    let c = v * s;
    let hp = (h - h.floor()) * 6.0;
    let x = c * (1.0 - ((hp - 2.0 * (hp * 0.5).floor()) - 1.0).abs());
    let (r, g, b) = match hp as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [(r + m) * 255.0, (g + m) * 255.0, (b + m) * 255.0]
}

/// Rotates the hue of an RGB (0..255) pixel by `degrees`, wrapping modulo 360°.
pub fn rotate_hue(rgb: [f32; 3], degrees: f32) -> [f32; 3] {
    let [h, s, v] = rgb_to_hsv(rgb);
    let turned = h + degrees / 360.0;
    hsv_to_rgb([turned - turned.floor(), s, v])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f32; 3], b: [f32; 3]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-3)
    }

    #[test]
    fn primaries_have_the_textbook_hsv() {
        assert!(close(rgb_to_hsv([255.0, 0.0, 0.0]), [0.0, 1.0, 1.0]));
        assert!(close(rgb_to_hsv([0.0, 255.0, 0.0]), [1.0 / 3.0, 1.0, 1.0]));
        assert!(close(rgb_to_hsv([0.0, 0.0, 255.0]), [2.0 / 3.0, 1.0, 1.0]));
        assert!(close(rgb_to_hsv([0.0, 0.0, 0.0]), [0.0, 0.0, 0.0]));
        assert!(close(
            rgb_to_hsv([255.0, 0.0, 255.0]),
            [5.0 / 6.0, 1.0, 1.0]
        ));
    }

    #[test]
    fn hsv_round_trips() {
        for rgb in [[12.0, 200.0, 99.0], [250.0, 3.0, 40.0], [7.0, 7.0, 7.0]] {
            assert!(close(hsv_to_rgb(rgb_to_hsv(rgb)), rgb));
        }
    }

    #[test]
    fn hue_rotation_wraps_modulo_360() {
        let red = [255.0, 0.0, 0.0];
        assert!(close(rotate_hue(red, 120.0), [0.0, 255.0, 0.0]));
        assert!(close(rotate_hue(red, 480.0), [0.0, 255.0, 0.0]));
        assert!(close(rotate_hue(red, -120.0), [0.0, 0.0, 255.0]));
        assert!(close(rotate_hue(red, 360.0), red));
    }
}
