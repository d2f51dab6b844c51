//! Shared fixtures: the 2D generator over the bundled libraries, which are
//! scanned once per test binary.

use matseg_image::PhotoLibrary;
use matseg_net::data::GeneratorSource;
use matseg_scene::{Recipe2d, Sources};
use std::path::Path;
use std::sync::OnceLock;

/// The generator over the bundled photos and textures.
pub fn generator(recipe: Recipe2d, seed: u64) -> GeneratorSource<'static> {
    static LIBRARIES: OnceLock<(PhotoLibrary, PhotoLibrary)> = OnceLock::new();
    let (photos, textures) = LIBRARIES.get_or_init(|| {
        let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets");
        let scan = |sub: &str| PhotoLibrary::scan(&[assets.join(sub)], 1 << 30).unwrap().0;
        (scan("photos"), scan("textures"))
    });
    GeneratorSource {
        sources: Sources { photos, textures },
        recipe,
        seed,
    }
}
