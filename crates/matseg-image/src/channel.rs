//! The six image channels a soft map can be cut from.

use crate::color::{hue, saturation, value};
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
    /// Hue (fraction of a turn).
    H,
    /// Saturation.
    S,
    /// Value (max of R, G, B).
    V,
}

impl Channel {
    /// The RGB channels.
    pub const RGB: [Channel; 3] = [Channel::R, Channel::G, Channel::B];
    /// The HSV channels.
    pub const HSV: [Channel; 3] = [Channel::H, Channel::S, Channel::V];

    /// The channel's value for an RGB (0..255) pixel, on its full range `[0, 1]`.
    #[inline]
    pub fn value(self, rgb: [f32; 3]) -> f32 {
        match self {
            Channel::R => rgb[0] / 255.0,
            Channel::G => rgb[1] / 255.0,
            Channel::B => rgb[2] / 255.0,
            Channel::H => hue(rgb),
            Channel::S => saturation(rgb),
            Channel::V => value(rgb),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_on_the_unit_range() {
        let px = [255.0, 127.5, 0.0];
        assert_eq!(Channel::R.value(px), 1.0);
        assert_eq!(Channel::G.value(px), 0.5);
        assert_eq!(Channel::B.value(px), 0.0);
        assert_eq!(Channel::V.value(px), 1.0);
        assert_eq!(Channel::S.value(px), 1.0);
        assert!((Channel::H.value(px) - 1.0 / 12.0).abs() < 1e-6);
    }
}
