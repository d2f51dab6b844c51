//! Photos inside Enlightenment's Eet archives (`.edj`, as Debian's
//! `enlightenment-data` ships its backgrounds): each archive holds one photo
//! as several JPEG files of decreasing size, stored as they are. The photo is
//! the largest of them whose longer side is at most [`MAX_EET_SIDE`], cut
//! out byte for byte (no re-encoding): found by its JPEG markers, sized by
//! its frame header, ended by its end-of-image marker.

use crate::error::{content, AssetError};

/// The longest side of the JPEG taken from an archive: the 2D generator's
/// scenes are at most 999 pixels, so larger copies only cost memory.
pub const MAX_EET_SIDE: u32 = 4096;

/// A JPEG found inside a file: its byte range and size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct EmbeddedJpeg {
    start: usize,
    end: usize,
    width: u32,
    height: u32,
}

/// The JPEG that starts at `start` (its start-of-image marker), if the
/// bytes from there are one: its end and frame size.
fn jpeg_at(bytes: &[u8], start: usize) -> Option<EmbeddedJpeg> {
    let byte = |i: usize| bytes.get(i).copied();
    let u16_at = |i: usize| Some(u16::from_be_bytes([byte(i)?, byte(i + 1)?]));
    let mut i = start + 2;
    let mut size = None;
    loop {
        if byte(i)? != 0xff {
            return None;
        }
        let marker = byte(i + 1)?;
        match marker {
            0xff => i += 1,
            0xd9 => {
                let (width, height) = size?;
                return Some(EmbeddedJpeg {
                    start,
                    end: i + 2,
                    width,
                    height,
                });
            }
            0x01 | 0xd0..=0xd7 => i += 2,
            _ => {
                let length = u16_at(i + 2)? as usize;
                if matches!(marker, 0xc0..=0xc3 | 0xc5..=0xc7 | 0xc9..=0xcb | 0xcd..=0xcf) {
                    size = Some((u16_at(i + 7)? as u32, u16_at(i + 5)? as u32));
                }
                i += 2 + length;
                if marker == 0xda {
                    // Entropy-coded data: up to the next marker that is not a
                    // stuffed 0xff or a restart marker.
                    loop {
                        if byte(i)? == 0xff && !matches!(byte(i + 1)?, 0x00 | 0xd0..=0xd7) {
                            break;
                        }
                        i += 1;
                    }
                }
            }
        }
    }
}

/// The photo of an Eet archive: the bytes of its largest JPEG whose longer
/// side is at most [`MAX_EET_SIDE`].
pub fn eet_photo(bytes: &[u8]) -> Result<Vec<u8>, AssetError> {
    let mut best: Option<EmbeddedJpeg> = None;
    let mut at = 0;
    while let Some(found) = bytes[at..].windows(3).position(|w| w == [0xff, 0xd8, 0xff]) {
        let start = at + found;
        at = start + 3;
        let Some(jpeg) = jpeg_at(bytes, start) else {
            continue;
        };
        let side = jpeg.width.max(jpeg.height);
        if side <= MAX_EET_SIDE && best.is_none_or(|b| side > b.width.max(b.height)) {
            best = Some(jpeg);
        }
    }
    let best = best.ok_or_else(|| {
        content(format!(
            "no JPEG of at most {MAX_EET_SIDE} pixels a side inside the Eet archive"
        ))
    })?;
    Ok(bytes[best.start..best.end].to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jpeg(w: u32, h: u32) -> Vec<u8> {
        let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, 7]));
        matseg_image::io::encode_jpeg(&img, 90)
    }

    #[test]
    fn the_largest_jpeg_within_the_limit_is_cut_out_whole() {
        let (large, medium, small) = (jpeg(4100, 8), jpeg(300, 200), jpeg(30, 20));
        let mut archive = b"\x1e\xe7\x0f\x42 header".to_vec();
        for part in [&large, &small, &medium] {
            archive.extend(b"entry header \xff\xd8 not a jpeg");
            archive.extend(part.iter());
        }
        archive.extend(b"dictionary");
        assert_eq!(eet_photo(&archive).unwrap(), medium);
        let err = eet_photo(b"\x1e\xe7\x0f\x42 nothing").unwrap_err();
        assert!(err.to_string().contains("no JPEG"), "{err}");
    }
}
