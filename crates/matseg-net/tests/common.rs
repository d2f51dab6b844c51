//! Shared fixtures: the 2D generator over the bundled libraries, which are
//! scanned once per test binary, and the tiny net the training tests run.

use matseg_image::PhotoLibrary;
use matseg_net::data::GeneratorSource;
use matseg_net::{ConvNextConfig, EncoderConfig, NetConfig};
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

/// The tiny ConvNeXt net the training tests run (one block a stage, 8 to 24
/// channels wide, 8-dimensional descriptors), with or without the encoder's
/// and the colour features beside the decoder's (`side_features`).
#[allow(dead_code)] // the overfitting test trains a wider net of its own
pub fn tiny_net(side_features: bool) -> NetConfig {
    NetConfig {
        encoder: EncoderConfig::Convnext(ConvNextConfig {
            depths: [1, 1, 1, 1],
            dims: [8, 16, 16, 24],
        }),
        psp_branch: 8,
        psp_out: 16,
        decoder: [16, 16, 8],
        descriptor_dim: 8,
        encoder_features: side_features,
        colour_features: side_features,
    }
}
