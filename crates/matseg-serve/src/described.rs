//! Photos described once: the model's coarse descriptors of each photo a
//! page opened, kept in a byte-bounded cache (least recently used first
//! out), so every click on a described photo is answered from memory.

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
