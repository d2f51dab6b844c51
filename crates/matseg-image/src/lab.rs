//! 8-bit sRGB levels as linear light (what the renderer's colour maps
//! read), and CIE L*a*b* (D65 white) of sRGB colours: the colour space of
//! the `lab` baseline and of the net's colour part, which share these
//! constants so that both convert alike.

/// Linear sRGB to CIE XYZ, rows X, Y, Z.
pub const LINEAR_SRGB_TO_XYZ: [[f32; 3]; 3] = [
    [0.4124, 0.3576, 0.1805],
    [0.2126, 0.7152, 0.0722],
    [0.0193, 0.1192, 0.9505],
];

/// The D65 white point's X and Z (Y is 1), by which X and Z are divided.
pub const D65_WHITE_XZ: [f32; 2] = [0.95047, 1.08883];

/// Where CIE Lab's f(t) turns from linear to a cube root: (6/29)^3.
pub const LAB_EPSILON: f32 = 216.0 / 24389.0;

/// The slope of f(t)'s linear part, (29/3)^3 (f(t) = (KAPPA t + 16) / 116).
pub const LAB_KAPPA: f32 = 24389.0 / 27.0;

/// CIE L*a*b* (D65 white) of an 8-bit sRGB colour.
pub fn srgb_to_lab(rgb: [u8; 3]) -> [f32; 3] {
    let table = linear_table();
    let [r, g, b] = rgb.map(|v| table[v as usize]);
    // sRGB to XYZ, normalised by the D65 white point.
    let [mx, my, mz] = LINEAR_SRGB_TO_XYZ;
    let x = (mx[0] * r + mx[1] * g + mx[2] * b) / D65_WHITE_XZ[0];
    let y = my[0] * r + my[1] * g + my[2] * b;
    let z = (mz[0] * r + mz[1] * g + mz[2] * b) / D65_WHITE_XZ[1];
    let f = |t: f32| {
        if t > LAB_EPSILON {
            t.cbrt()
        } else {
            (LAB_KAPPA * t + 16.0) / 116.0
        }
    };
    let (fx, fy, fz) = (f(x), f(y), f(z));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// Linear light of each 8-bit sRGB level (the sRGB transfer function
/// undone), computed once.
pub fn linear_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|v| {
            let c = v as f32 / 255.0;
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lab_of_reference_colours() {
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 0.05);
        assert!(close(srgb_to_lab([255, 255, 255]), [100.0, 0.0, 0.0]));
        assert!(close(srgb_to_lab([0, 0, 0]), [0.0, 0.0, 0.0]));
        // Published sRGB red: L 53.24, a 80.09, b 67.20.
        let red = srgb_to_lab([255, 0, 0]);
        assert!((red[0] - 53.24).abs() < 0.1 && (red[1] - 80.09).abs() < 0.2);
        assert!((red[2] - 67.20).abs() < 0.2);
    }
}
