//! A tiny net overfits four fixed generated samples: the loss, the net and
//! the optimiser are wired so that training drives the loss far down.

mod common;

use matseg_net::data::SampleSource;
use matseg_net::{
    matseg_loss, Batch, ConvNextConfig, EncoderConfig, MaterialNet, NetConfig, TrainingSample,
};
use matseg_scene::Recipe2d;
use tch::nn::{self, OptimizerConfig};
use tch::Device;

const SIDE: usize = 64;

/// Four generated 64x64 samples read back as training reads them (masks
/// quantised to 8 bits; weights = mask / sum, ROI = sum >= 10).
fn samples() -> Vec<TrainingSample> {
    let mut recipe = Recipe2d::default();
    recipe.scene.size_min = SIDE;
    recipe.scene.size_max = SIDE;
    recipe.scene.materials_max = 3;
    let generator = common::generator(recipe, 0);
    (0..4).map(|i| generator.sample(i).unwrap()).collect()
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
        encoder_features: false,
        colour_features: false,
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
