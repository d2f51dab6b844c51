//! What the server keeps in memory, within one byte budget: photos the
//! model described (their pixels and coarse descriptors, so every click on
//! a described photo is answered from memory) and photos the page
//! uploaded (their encoded bytes). Least recently used first out.

use image::RgbImage;
use matseg_image::coarse::CoarseDescriptors;
use matseg_image::ByteLru;

/// A photo and its descriptors.
pub struct Described {
    /// The photo's pixels.
    pub photo: RgbImage,
    /// The model's descriptors of it.
    pub map: CoarseDescriptors,
}

impl Described {
    /// Bytes it holds.
    pub fn bytes(&self) -> usize {
        self.photo.as_raw().len() + 4 * self.map.grid.data.len()
    }
}

/// Described photos by key (root and file).
pub type DescribedCache = ByteLru<String, Described>;

/// Uploaded photos (PNG or JPEG bytes as sent) by name.
pub type Uploads = ByteLru<String, Vec<u8>>;
