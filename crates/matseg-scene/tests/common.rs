//! Shared test fixtures: the bundled libraries and a small-scene recipe.

use matseg_image::PhotoLibrary;
use matseg_scene::Recipe2d;
use std::path::Path;

/// The bundled photos and textures.
pub fn libraries() -> (PhotoLibrary, PhotoLibrary) {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets");
    let scan = |sub: &str| PhotoLibrary::scan(&[assets.join(sub)], 1 << 30).unwrap().0;
    (scan("photos"), scan("textures"))
}

/// The default recipe with small scenes, so tests stay fast.
pub fn small_recipe() -> Recipe2d {
    let mut r = Recipe2d::default();
    r.scene.size_min = 64;
    r.scene.size_max = 160;
    r
}
