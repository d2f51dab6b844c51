//! What the server keeps in memory, within one byte budget: photos the
//! model described (their pixels and coarse descriptors, so every click on
//! a described photo is answered from memory) and photos the page
//! uploaded (their encoded bytes). Least recently used first out.

use image::RgbImage;
use matseg_image::ByteLru;
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::select::PhotoPrep;
use std::sync::Arc;

/// A photo, its descriptors, and what its selections prepared of it.
pub struct Described {
    /// The photo's pixels.
    pub photo: RgbImage,
    /// The model's descriptors of it.
    pub map: CoarseDescriptors,
    /// Shared by every selection on the photo, made with the photo's
    /// description so that no click waits for it.
    pub prep: Arc<PhotoPrep>,
}

impl Described {
    /// `photo` and its descriptors `map`, with the preparation of its
    /// selections.
    pub fn new(photo: RgbImage, map: CoarseDescriptors) -> Self {
        let prep = PhotoPrep::default();
        prep.prepare(&map, Some(&photo));
        Self {
            photo,
            map,
            prep: Arc::new(prep),
        }
    }

    /// Bytes it holds, its selections' preparation counted at its most.
    pub fn bytes(&self) -> usize {
        let grid = &self.map.grid;
        self.photo.as_raw().len()
            + 4 * grid.data.len()
            + PhotoPrep::bytes_at_most(
                self.map.width,
                self.map.height,
                grid.width * grid.height,
                grid.dim,
            )
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
