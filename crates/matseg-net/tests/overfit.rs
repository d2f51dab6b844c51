//! A tiny net overfits four fixed generated samples: the loss, the net and
//! the optimiser are wired so that training drives the loss far down.

use image::GrayImage;
use matseg_data::Sample;
use matseg_image::PhotoLibrary;
use matseg_net::{
    matseg_loss, Batch, ConvNextConfig, EncoderConfig, MaterialNet, NetConfig, TrainingSample,
};
use matseg_scene::{generate_2d, quantise_weights, Recipe2d, Sources};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use tch::nn::{self, OptimizerConfig};
use tch::Device;

const SIDE: usize = 64;

/// Four generated 64x64 samples read back as training reads them (masks
/// quantised to 8 bits; weights = mask / sum, ROI = sum >= 10).
fn samples() -> Vec<TrainingSample> {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets");
    let photos = PhotoLibrary::scan(&[assets.join("photos")], 1 << 30)
        .unwrap()
        .0;
    let textures = PhotoLibrary::scan(&[assets.join("textures")], 1 << 30)
        .unwrap()
        .0;
    let sources = Sources {
        photos: &photos,
        textures: &textures,
    };
    let mut recipe = Recipe2d::default();
    recipe.scene.size_min = SIDE;
    recipe.scene.size_max = SIDE;
    recipe.scene.materials_max = 3;
    (0..4u64)
        .map(|seed| {
            let scene =
                generate_2d(&mut ChaCha8Rng::seed_from_u64(seed), &recipe, sources).unwrap();
            let q = quantise_weights(&scene.weights, &scene.background);
            let masks = q
                .masks
                .into_iter()
                .map(|m| GrayImage::from_raw(SIDE as u32, SIDE as u32, m).unwrap())
                .collect();
            TrainingSample::from_sample(Sample {
                key: seed.to_string(),
                image: scene.image,
                masks,
                roi: None,
                meta: None,
            })
        })
        .collect()
}

#[test]
fn a_tiny_net_overfits_four_samples() {
    tch::manual_seed(0);
    let batch = Batch::new(&samples(), Device::Cpu);
    let config = NetConfig {
        encoder: EncoderConfig::Convnext(ConvNextConfig {
            depths: [1, 1, 1, 1],
            dims: [16, 24, 32, 48],
        }),
        psp_branch: 16,
        psp_out: 32,
        decoder: [32, 24, 16],
        descriptor_dim: 16,
    };
    let vs = nn::VarStore::new(Device::Cpu);
    let net = MaterialNet::new(&vs.root(), config);
    let mut opt = nn::Adam::default().build(&vs, 3e-3).unwrap();
    let mut losses = Vec::new();
    for _ in 0..200 {
        let descriptors = net.forward_t(&batch.images, true);
        let loss = matseg_loss(&descriptors, &batch.targets).expect("several materials");
        opt.backward_step(&loss);
        losses.push(loss.double_value(&[]));
    }
    let first = losses[0];
    let last = losses[losses.len() - 10..].iter().sum::<f64>() / 10.0;
    eprintln!("loss {first:.4} -> {last:.4}");
    assert!(last < 0.25 * first, "loss {first} -> {last}");
}
