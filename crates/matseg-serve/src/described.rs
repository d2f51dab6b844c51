//! What the server keeps in memory, within one byte budget: photos the
//! model described (their pixels and coarse descriptors, so every click on
//! a described photo is answered from memory) and photos the page
//! uploaded (their encoded bytes). Least recently used first out.

use image::RgbImage;
use matseg_image::ByteLru;
use matseg_query::coarse::CoarseDescriptors;

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

/// Gives the memory freed since the last call back to the system (glibc:
/// `malloc_trim`; elsewhere nothing). Describing a photo allocates and
/// frees hundreds of MiB of tensors between the described photos kept in
/// the heap; without this, the holes they leave are kept and the server's
/// memory grows far past its cache bound.
pub fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free pages of the heap to the system.
    unsafe {
        libc::malloc_trim(0);
    }
}
