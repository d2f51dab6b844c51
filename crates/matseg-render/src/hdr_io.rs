//! High-dynamic-range images: Radiance `.hdr` (RGBE, flat or run-length
//! encoded) read and written here, and OpenEXR (ZIP, PIZ, RLE, B44, DWAA,
//! DWAB, ...) read through the `exr` crate. Values are linear float RGB.

use crate::content::ContentError;
use crate::math::Vec3;
use std::path::Path;

/// A linear RGB float image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct HdrImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Pixels.
    pub pixels: Vec<Vec3>,
}

impl HdrImage {
    /// Largest and mean luminance (Rec. 709) of an equirectangular map, the
    /// mean weighted by each row's solid angle.
    pub fn luminance_stats(&self) -> (f32, f32) {
        let (w, h) = (self.width, self.height);
        let (mut sum, mut weight, mut max) = (0f64, 0f64, 0f32);
        for y in 0..h {
            let sin = (std::f32::consts::PI * (y as f32 + 0.5) / h as f32).sin() as f64;
            for p in &self.pixels[y * w..(y + 1) * w] {
                sum += p.luminance() as f64 * sin;
                weight += sin;
                max = max.max(p.luminance());
            }
        }
        (max, (sum / weight.max(f64::MIN_POSITIVE)) as f32)
    }
}

/// An HDR file that could not be read or written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct HdrError {
    /// The file.
    pub path: String,
    /// What went wrong.
    pub message: String,
}

/// The extensions [`read_hdr`] understands.
pub const HDR_EXTENSIONS: [&str; 2] = ["hdr", "exr"];

/// Reads a `.hdr` or `.exr` file (by extension); negative values become 0.
pub fn read_hdr(path: &Path) -> Result<HdrImage, HdrError> {
    let fail = |message: String| HdrError {
        path: path.display().to_string(),
        message,
    };
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_lowercase)
        .unwrap_or_default();
    let img = match ext.as_str() {
        "hdr" => {
            let bytes = std::fs::read(path).map_err(|e| fail(format!("cannot read: {e}")))?;
            decode_radiance(&bytes).map_err(|e| fail(e.0))?
        }
        "exr" => read_exr(path).map_err(|e| fail(e.0))?,
        _ => return Err(fail("not an .hdr or .exr file".into())),
    };
    if img.pixels.iter().any(|p| !p.is_finite()) {
        return Err(fail("has non-finite pixels".into()));
    }
    // Lossy EXR codecs leave small negative values in dark pixels;
    // radiance cannot be negative.
    let mut img = img;
    img.pixels.iter_mut().for_each(|p| *p = p.max(Vec3::ZERO));
    Ok(img)
}

fn read_exr(path: &Path) -> Result<HdrImage, ContentError> {
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| HdrImage {
            width: resolution.width(),
            height: resolution.height(),
            pixels: vec![Vec3::ZERO; resolution.width() * resolution.height()],
        },
        |img: &mut HdrImage, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            img.pixels[pos.y() * img.width + pos.x()] = Vec3::new(r, g, b);
        },
    )
    .map_err(|e| match e {
        Error::NotSupported(what) => format!("unsupported EXR feature: {what}"),
        other => other.to_string(),
    })?;
    Ok(image.layer_data.channel_data.pixels)
}

/// One RGBE pixel to linear RGB.
fn rgbe_to_rgb([r, g, b, e]: [u8; 4]) -> Vec3 {
    if e == 0 {
        return Vec3::ZERO;
    }
    let f = 2f32.powi(e as i32 - 136);
    Vec3::new(r as f32 + 0.5, g as f32 + 0.5, b as f32 + 0.5) * f
}

/// Linear RGB to RGBE (shared exponent of the largest component).
fn rgb_to_rgbe(c: Vec3) -> [u8; 4] {
    let m = c.max_elem();
    if m < 1e-32 {
        return [0; 4];
    }
    // m = mantissa * 2^exp with mantissa in [0.5, 1).
    let exp = m.log2().floor() as i32 + 1;
    let scale = 256.0 / 2f32.powi(exp);
    let q = |v: f32| (v * scale).clamp(0.0, 255.0) as u8;
    [q(c.x), q(c.y), q(c.z), (exp + 128).clamp(0, 255) as u8]
}

/// Decodes a Radiance file's bytes.
fn decode_radiance(bytes: &[u8]) -> Result<HdrImage, ContentError> {
    if !bytes.starts_with(b"#?") {
        return Err("not a Radiance HDR file (no #? signature)".into());
    }
    // Header lines up to an empty line, then the resolution line.
    let mut at = 0;
    let mut line = || -> Result<String, String> {
        let end = bytes[at..]
            .iter()
            .position(|&b| b == b'\n')
            .ok_or("header ends early")?;
        let s = String::from_utf8_lossy(&bytes[at..at + end])
            .trim()
            .to_string();
        at += end + 1;
        Ok(s)
    };
    loop {
        let l = line()?;
        if l.starts_with("FORMAT=") && l != "FORMAT=32-bit_rle_rgbe" {
            return Err(format!("unsupported {l}").into());
        }
        if l.is_empty() {
            break;
        }
    }
    let res = line()?;
    let parts: Vec<&str> = res.split_whitespace().collect();
    let (height, width) = match parts.as_slice() {
        ["-Y", h, "+X", w] => (
            h.parse::<usize>()
                .map_err(|_| format!("bad resolution {res:?}"))?,
            w.parse::<usize>()
                .map_err(|_| format!("bad resolution {res:?}"))?,
        ),
        _ => return Err(format!("unsupported orientation {res:?} (only -Y H +X W)").into()),
    };
    if width == 0 || height == 0 || width > 1 << 16 || height > 1 << 16 {
        return Err(format!("bad size {width}x{height}").into());
    }
    let mut data = &bytes[at..];
    let mut pixels = Vec::with_capacity(width * height);
    let mut row = vec![[0u8; 4]; width];
    for y in 0..height {
        let short = || format!("pixel data ends early at row {y}");
        let rle = (8..32768).contains(&width)
            && data.len() >= 4
            && data[0] == 2
            && data[1] == 2
            && data[2] & 0x80 == 0;
        if rle {
            if ((data[2] as usize) << 8 | data[3] as usize) != width {
                return Err(format!("row {y}: run-length row of the wrong width").into());
            }
            data = &data[4..];
            for c in 0..4 {
                let mut x = 0;
                while x < width {
                    let (&n, rest) = data.split_first().ok_or_else(short)?;
                    data = rest;
                    if n > 128 {
                        let n = (n - 128) as usize;
                        let (&v, rest) = data.split_first().ok_or_else(short)?;
                        data = rest;
                        if x + n > width {
                            return Err(format!("row {y}: run past the end of the row").into());
                        }
                        row[x..x + n].iter_mut().for_each(|p| p[c] = v);
                        x += n;
                    } else {
                        let n = n as usize;
                        if n == 0 || x + n > width || data.len() < n {
                            return Err(if data.len() < n {
                                short()
                            } else {
                                format!("row {y}: bad run")
                            }
                            .into());
                        }
                        for (p, &v) in row[x..x + n].iter_mut().zip(&data[..n]) {
                            p[c] = v;
                        }
                        data = &data[n..];
                        x += n;
                    }
                }
            }
        } else {
            if data.len() < 4 * width {
                return Err(short().into());
            }
            for (p, chunk) in row.iter_mut().zip(data.chunks_exact(4)) {
                *p = [chunk[0], chunk[1], chunk[2], chunk[3]];
            }
            data = &data[4 * width..];
        }
        pixels.extend(row.iter().map(|&p| rgbe_to_rgb(p)));
    }
    Ok(HdrImage {
        width,
        height,
        pixels,
    })
}

/// Encodes an image as a run-length encoded Radiance file.
pub fn encode_radiance(img: &HdrImage) -> Vec<u8> {
    let mut out = format!(
        "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nSOFTWARE=matseg\n\n-Y {} +X {}\n",
        img.height, img.width
    )
    .into_bytes();
    let rle = img.width >= 8 && img.width < 32768;
    for row in img.pixels.chunks_exact(img.width) {
        let rgbe: Vec<[u8; 4]> = row.iter().map(|&c| rgb_to_rgbe(c)).collect();
        if !rle {
            rgbe.iter().for_each(|p| out.extend_from_slice(p));
            continue;
        }
        out.extend_from_slice(&[2, 2, (img.width >> 8) as u8, img.width as u8]);
        for c in 0..4 {
            let values: Vec<u8> = rgbe.iter().map(|p| p[c]).collect();
            encode_channel_runs(&values, &mut out);
        }
    }
    out
}

/// Runs of 3+ equal bytes as (128 + n, value); the rest as literal blocks
/// of up to 128.
fn encode_channel_runs(values: &[u8], out: &mut Vec<u8>) {
    let mut x = 0;
    while x < values.len() {
        let mut run = 1;
        while x + run < values.len() && run < 127 && values[x + run] == values[x] {
            run += 1;
        }
        if run >= 3 {
            out.extend_from_slice(&[128 + run as u8, values[x]]);
            x += run;
            continue;
        }
        // A literal block up to the next run of 3 (or 128 bytes).
        let start = x;
        while x < values.len() && x - start < 128 {
            if x + 2 < values.len() && values[x] == values[x + 1] && values[x] == values[x + 2] {
                break;
            }
            x += 1;
        }
        out.push((x - start) as u8);
        out.extend_from_slice(&values[start..x]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(width: usize, height: usize) -> HdrImage {
        HdrImage {
            width,
            height,
            pixels: (0..width * height)
                .map(|i| {
                    let (x, y) = ((i % width) as f32, (i / width) as f32);
                    // Runs (the constant blocks) and a wide dynamic range.
                    Vec3::new(
                        (x / 4.0).floor() * 3.0,
                        0.001 * (y + 1.0),
                        if x > 5.0 { 5000.0 } else { 0.0 },
                    )
                })
                .collect(),
        }
    }

    #[test]
    fn luminance_stats_weight_rows_by_solid_angle() {
        // Two rows: the weights are equal (sin(pi/4) = sin(3pi/4)).
        let grey = |v: f32| Vec3::new(v, v, v);
        let img = HdrImage {
            width: 2,
            height: 2,
            pixels: vec![grey(1.0), grey(3.0), grey(0.0), grey(0.0)],
        };
        let (max, mean) = img.luminance_stats();
        assert!((max - 3.0).abs() < 1e-6);
        assert!((mean - 1.0).abs() < 1e-6);
    }

    #[test]
    fn dwab_exrs_read_within_their_lossy_precision() {
        use exr::prelude::*;
        let (w, h) = (96, 64);
        let value =
            |x: usize, y: usize| Vec3::new(x as f32 * 0.25 + 1.0, y as f32 * 0.5 + 0.1, 3.0);
        let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
            let v = value(p.x(), p.y());
            (f16::from_f32(v.x), f16::from_f32(v.y), f16::from_f32(v.z))
        });
        let encoding = Encoding {
            compression: Compression::DWAB(None),
            ..Encoding::default()
        };
        let layer = Layer::new((w, h), LayerAttributes::named("rgb"), encoding, channels);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("dwab.exr");
        Image::from_layer(layer).write().to_file(&path).unwrap();
        let raw = (w * h * 3 * 2) as u64;
        assert!(
            std::fs::metadata(&path).unwrap().len() < raw / 2,
            "really DWAB-compressed"
        );
        let img = read_hdr(&path).unwrap();
        assert_eq!((img.width, img.height), (w, h));
        for y in 0..h {
            for x in 0..w {
                let (got, want) = (img.pixels[y * w + x], value(x, y));
                let errors = [got.x - want.x, got.y - want.y, got.z - want.z];
                assert!(
                    errors.iter().all(|e| e.abs() <= 0.02 * want.max_elem()),
                    "({x}, {y}): {got:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn radiance_round_trips_within_rgbe_precision() {
        for (w, h) in [(40, 3), (5, 2)] {
            let img = gradient(w, h);
            let back = decode_radiance(&encode_radiance(&img)).unwrap();
            assert_eq!((back.width, back.height), (w, h));
            for (a, b) in img.pixels.iter().zip(&back.pixels) {
                // RGBE keeps ~8 bits of mantissa relative to the largest channel.
                let tol = a.max_elem() / 128.0 + 1e-30;
                assert!(
                    (*a - *b).max_elem().abs() <= tol && (*b - *a).max_elem() <= tol,
                    "{a:?} vs {b:?}"
                );
            }
        }
    }

    #[test]
    fn truncated_and_foreign_files_are_refused() {
        let bytes = encode_radiance(&gradient(40, 3));
        let err = decode_radiance(&bytes[..bytes.len() - 10]).unwrap_err().0;
        assert!(err.contains("ends early at row 2"), "{err}");
        assert!(decode_radiance(b"P6\n")
            .unwrap_err()
            .0
            .contains("no #? signature"));
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.exr");
        std::fs::write(&p, b"not an exr").unwrap();
        let err = read_hdr(&p).unwrap_err().to_string();
        assert!(err.starts_with(&p.display().to_string()), "{err}");
    }
}
