//! DirectDraw Surface (`.dds`) textures, as games ship them: the first
//! (largest) mipmap level decoded to RGB. Block-compressed BC1 (`DXT1`),
//! BC2 (`DXT3`) and BC3 (`DXT5`), and uncompressed RGB or RGBA given by
//! channel bit masks. Alpha is dropped: matseg's textures are RGB.

use crate::error::{content, AssetError};

/// The size of the header after the `DDS ` magic.
const HEADER_SIZE: usize = 124;
/// Pixel-format flag: the format is a FourCC code (compressed).
const PF_FOURCC: u32 = 0x4;
/// Pixel-format flag: uncompressed RGB with bit masks.
const PF_RGB: u32 = 0x40;

/// A decoded texture.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DdsImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major RGB, 3 bytes a pixel.
    pub rgb: Vec<u8>,
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

/// Decodes the largest mipmap level of a `.dds` file to RGB; the error says
/// what is wrong (not a DDS file, a format not handled, truncated data).
pub fn decode_dds(bytes: &[u8]) -> Result<DdsImage, AssetError> {
    if bytes.len() < 4 + HEADER_SIZE || &bytes[..4] != b"DDS " {
        return Err(content(
            "not a DDS file (no `DDS ` magic and 124-byte header)",
        ));
    }
    let header = &bytes[4..4 + HEADER_SIZE];
    if u32_at(header, 0) as usize != HEADER_SIZE {
        return Err(content("DDS: bad header size"));
    }
    let (height, width) = (u32_at(header, 8), u32_at(header, 12));
    if width == 0 || height == 0 || width > 16_384 || height > 16_384 {
        return Err(content(format!("DDS: bad size {width}x{height}")));
    }
    // The pixel format starts at byte 72 of the header.
    let pf_flags = u32_at(header, 76);
    let fourcc = &header[80..84];
    let data = &bytes[4 + HEADER_SIZE..];
    let (w, h) = (width as usize, height as usize);
    let rgb = if pf_flags & PF_FOURCC != 0 {
        let (block_bytes, colour_offset) = match fourcc {
            b"DXT1" => (8, 0),
            b"DXT3" | b"DXT5" => (16, 8),
            other => {
                return Err(content(format!(
                    "DDS: compression {} not handled (DXT1, DXT3, DXT5)",
                    String::from_utf8_lossy(other).trim_end_matches('\0')
                )))
            }
        };
        decode_blocks(data, w, h, block_bytes, colour_offset, fourcc == b"DXT1")?
    } else if pf_flags & PF_RGB != 0 {
        let bits = u32_at(header, 84);
        let masks = [u32_at(header, 88), u32_at(header, 92), u32_at(header, 96)];
        decode_masked(data, w, h, bits, masks)?
    } else {
        return Err(content(
            "DDS: neither compressed nor RGB (luminance or YUV formats not handled)",
        ));
    };
    Ok(DdsImage { width, height, rgb })
}

/// An RGB565 colour widened to 8 bits a channel.
fn rgb565(c: u16) -> [u8; 3] {
    let (r, g, b) = ((c >> 11) & 31, (c >> 5) & 63, c & 31);
    [
        ((r << 3) | (r >> 2)) as u8,
        ((g << 2) | (g >> 4)) as u8,
        ((b << 3) | (b >> 2)) as u8,
    ]
}

/// The four colours of a BC1 colour block. In BC1 proper (`three_colour_mode`
/// allowed) `c0 <= c1` selects three colours and black (transparent); BC2 and
/// BC3 always interpolate four.
fn palette(c0: u16, c1: u16, three_colour_mode: bool) -> [[u8; 3]; 4] {
    let (a, b) = (rgb565(c0), rgb565(c1));
    let mix = |wa: u16, wb: u16| {
        let d = wa + wb;
        [0, 1, 2].map(|i| ((wa * a[i] as u16 + wb * b[i] as u16 + d / 2) / d) as u8)
    };
    if three_colour_mode && c0 <= c1 {
        [a, b, mix(1, 1), [0, 0, 0]]
    } else {
        [a, b, mix(2, 1), mix(1, 2)]
    }
}

/// Decodes 4x4 blocks of `block_bytes` bytes whose colour part (a BC1
/// block) starts at `colour_offset`.
fn decode_blocks(
    data: &[u8],
    w: usize,
    h: usize,
    block_bytes: usize,
    colour_offset: usize,
    bc1: bool,
) -> Result<Vec<u8>, AssetError> {
    let (bw, bh) = (w.div_ceil(4), h.div_ceil(4));
    let need = bw * bh * block_bytes;
    if data.len() < need {
        return Err(content(format!(
            "DDS: truncated ({} of {need} bytes of pixel data)",
            data.len()
        )));
    }
    let mut rgb = vec![0u8; w * h * 3];
    for (i, block) in data[..need].chunks_exact(block_bytes).enumerate() {
        let (bx, by) = (i % bw * 4, i / bw * 4);
        let c = &block[colour_offset..colour_offset + 8];
        let colours = palette(
            u16::from_le_bytes([c[0], c[1]]),
            u16::from_le_bytes([c[2], c[3]]),
            bc1,
        );
        let indices = u32_at(c, 4);
        for py in 0..4 {
            for px in 0..4 {
                let (x, y) = (bx + px, by + py);
                if x < w && y < h {
                    let k = (indices >> (2 * (4 * py + px))) & 3;
                    let at = (y * w + x) * 3;
                    rgb[at..at + 3].copy_from_slice(&colours[k as usize]);
                }
            }
        }
    }
    Ok(rgb)
}

/// One channel of a pixel `value` under `mask`, scaled to 8 bits.
fn channel(value: u32, mask: u32) -> u8 {
    if mask == 0 {
        return 0;
    }
    let max = mask >> mask.trailing_zeros();
    let v = (value & mask) >> mask.trailing_zeros();
    ((u64::from(v) * 255 + u64::from(max) / 2) / u64::from(max)) as u8
}

/// Decodes uncompressed pixels of `bits` bits (8, 16, 24 or 32) whose red,
/// green and blue are under `masks`; rows are packed.
fn decode_masked(
    data: &[u8],
    w: usize,
    h: usize,
    bits: u32,
    masks: [u32; 3],
) -> Result<Vec<u8>, AssetError> {
    if ![8, 16, 24, 32].contains(&bits) {
        return Err(content(format!("DDS: {bits} bits a pixel not handled")));
    }
    let bpp = bits as usize / 8;
    let need = w * h * bpp;
    if data.len() < need {
        return Err(content(format!(
            "DDS: truncated ({} of {need} bytes of pixel data)",
            data.len()
        )));
    }
    let mut rgb = Vec::with_capacity(w * h * 3);
    for px in data[..need].chunks_exact(bpp) {
        let mut word = [0u8; 4];
        word[..bpp].copy_from_slice(px);
        let value = u32::from_le_bytes(word);
        rgb.extend(masks.map(|m| channel(value, m)));
    }
    Ok(rgb)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A DDS header for `w x h` with pixel-format flags, FourCC, bit count
    /// and R, G, B masks.
    fn header(w: u32, h: u32, flags: u32, fourcc: &[u8; 4], bits: u32, masks: [u32; 3]) -> Vec<u8> {
        let mut out = b"DDS ".to_vec();
        let mut fields = [0u32; 31];
        fields[0] = HEADER_SIZE as u32;
        fields[1] = 0x1007; // caps, height, width, pixel format
        fields[2] = h;
        fields[3] = w;
        fields[18] = 32; // pixel format size
        fields[19] = flags;
        fields[20] = u32::from_le_bytes(*fourcc);
        fields[21] = bits;
        fields[22..25].copy_from_slice(&masks);
        for f in fields {
            out.extend(f.to_le_bytes());
        }
        out
    }

    /// A BC1 colour block: endpoints and one 2-bit index per pixel (row-major).
    fn colour_block(c0: u16, c1: u16, indices: [u32; 16]) -> Vec<u8> {
        let bits = indices
            .iter()
            .enumerate()
            .fold(0u32, |acc, (i, &k)| acc | k << (2 * i));
        [c0.to_le_bytes(), c1.to_le_bytes()]
            .concat()
            .into_iter()
            .chain(bits.to_le_bytes())
            .collect()
    }

    const RED: u16 = 31 << 11;
    const BLUE: u16 = 31;

    #[test]
    fn bc1_blocks_decode_to_their_palettes() {
        // Four-colour mode (c0 > c1): red, blue, 2/3 red + 1/3 blue, 1/3 red + 2/3 blue.
        let indices: [u32; 16] = std::array::from_fn(|i| (i % 4) as u32);
        let mut file = header(4, 4, PF_FOURCC, b"DXT1", 0, [0; 3]);
        file.extend(colour_block(RED, BLUE, indices));
        let img = decode_dds(&file).unwrap();
        assert_eq!((img.width, img.height), (4, 4));
        let row: Vec<u8> = img.rgb[..12].to_vec();
        assert_eq!(row, [255, 0, 0, 0, 0, 255, 170, 0, 85, 85, 0, 170]);
        // Every row is the same.
        assert!(img.rgb.chunks(12).all(|r| r == row));
        // Three-colour mode (c0 <= c1): the third is the mean, the fourth black.
        let mut file = header(4, 4, PF_FOURCC, b"DXT1", 0, [0; 3]);
        file.extend(colour_block(BLUE, RED, indices));
        let img = decode_dds(&file).unwrap();
        assert_eq!(img.rgb[..12], [0, 0, 255, 255, 0, 0, 128, 0, 128, 0, 0, 0]);
    }

    #[test]
    fn bc3_colour_is_always_four_colour_and_partial_blocks_are_cropped() {
        // 6x5 pixels: 2x2 blocks of 16 bytes (8 of alpha, ignored, then colour).
        let mut file = header(6, 5, PF_FOURCC, b"DXT5", 0, [0; 3]);
        for k in 0..4u32 {
            file.extend([0xffu8; 8]);
            file.extend(colour_block(BLUE, RED, [k.min(3); 16]));
        }
        let img = decode_dds(&file).unwrap();
        assert_eq!(img.rgb.len(), 6 * 5 * 3);
        // Block 0 is index 0 (blue); block 1 (x >= 4) index 1 (red); block 2
        // (y >= 4) index 2: 2/3 blue + 1/3 red, not BC1's mean.
        assert_eq!(img.rgb[..3], [0, 0, 255]);
        assert_eq!(img.rgb[4 * 3..5 * 3], [255, 0, 0]);
        let at = (4 * 6) * 3;
        assert_eq!(img.rgb[at..at + 3], [85, 0, 170]);
    }

    #[test]
    fn uncompressed_pixels_follow_their_masks() {
        // 32-bit BGRA (the usual D3D order) and 16-bit RGB565.
        let mut file = header(2, 1, PF_RGB | 1, b"\0\0\0\0", 32, [0xff0000, 0xff00, 0xff]);
        file.extend([10, 20, 30, 255, 1, 2, 3, 0]);
        assert_eq!(decode_dds(&file).unwrap().rgb, [30, 20, 10, 3, 2, 1]);
        let mut file = header(1, 1, PF_RGB, b"\0\0\0\0", 16, [0xf800, 0x07e0, 0x001f]);
        file.extend(RED.to_le_bytes());
        assert_eq!(decode_dds(&file).unwrap().rgb, [255, 0, 0]);
    }

    #[test]
    fn bad_files_are_named_errors() {
        assert!(decode_dds(b"PNG...")
            .unwrap_err()
            .to_string()
            .contains("not a DDS file"));
        let file = header(8, 8, PF_FOURCC, b"DXT1", 0, [0; 3]);
        assert!(decode_dds(&file)
            .unwrap_err()
            .to_string()
            .contains("truncated"));
        let file = header(8, 8, PF_FOURCC, b"DX10", 0, [0; 3]);
        assert!(decode_dds(&file)
            .unwrap_err()
            .to_string()
            .contains("DX10 not handled"));
        let file = header(0, 8, PF_FOURCC, b"DXT1", 0, [0; 3]);
        assert!(decode_dds(&file)
            .unwrap_err()
            .to_string()
            .contains("bad size"));
    }
}
