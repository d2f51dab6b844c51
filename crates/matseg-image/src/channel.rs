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

/// Fixed-point bits of the reciprocal tables.
const SHIFT: u32 = 12;

/// `round(2^SHIFT * 256 / (6 d))`: hue levels per sextant unit, for a spread `d`.
const HUE_RECIPROCAL: [i32; 256] = reciprocals(256 << SHIFT, 6);

/// `round(2^SHIFT * 255 / m)`: saturation levels per unit of spread, for a max `m`.
const SATURATION_RECIPROCAL: [i32; 256] = reciprocals(255 << SHIFT, 1);

/// `round(numerator / (divisor * i))` for i in 1..=255 (0 for i = 0).
const fn reciprocals(numerator: i64, divisor: i64) -> [i32; 256] {
    let mut table = [0i32; 256];
    let mut i = 1;
    while i < 256 {
        let d = divisor * i as i64;
        table[i] = ((numerator + d / 2) / d) as i32;
        i += 1;
    }
    table
}

/// Hue level of an 8-bit pixel: `round(256 * hue / 360°)` modulo 256 (0 for
/// greys), in integer arithmetic without branches on the colour.
#[inline]
pub fn hue_level([r, g, b]: [u8; 3]) -> u8 {
    let (r, g, b) = (r as i32, g as i32, b as i32);
    let max = r.max(g).max(b);
    let spread = max - r.min(g).min(b);
    // Numerator of the sextant position, in [-spread, 5 * spread].
    let sextant = if max == r {
        g - b
    } else if max == g {
        b - r + 2 * spread
    } else {
        r - g + 4 * spread
    };
    let h = (sextant * HUE_RECIPROCAL[spread as usize] + (1 << (SHIFT - 1))) >> SHIFT;
    (h & 255) as u8
}

/// Saturation level of an 8-bit pixel: `round(255 * (max - min) / max)`, 0 for black.
#[inline]
pub fn saturation_level([r, g, b]: [u8; 3]) -> u8 {
    let max = r.max(g).max(b);
    let spread = (max - r.min(g).min(b)) as i32;
    let s = (spread * SATURATION_RECIPROCAL[max as usize] + (1 << (SHIFT - 1))) >> SHIFT;
    s.min(255) as u8
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::{hue, saturation};

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

    #[test]
    fn levels_round_the_exact_hue_and_saturation() {
        // Rounding (0.5) plus the fixed-point reciprocal's error (< 0.2 level).
        const MAX_OFF: f32 = 0.7;
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
