//! Shapes and normalisation of every block, and parameter counts that pin
//! the architectures to their references.

use matseg_net::blocks::l2_normalise;
use matseg_net::colour::COLOUR_FEATURES;
use matseg_net::convnext::ConvNext;
use matseg_net::decoder::Decoder;
use matseg_net::psp::Psp;
use matseg_net::{
    normalise_input, rgb8_to_tensor, ConvNextConfig, EncoderConfig, MaterialNet, MobileNetV2,
    MobileNetV2Classifier, NetConfig,
};
use tch::{nn, Device, Kind, Tensor};

fn parameters(vs: &nn::VarStore) -> i64 {
    vs.trainable_variables()
        .iter()
        .map(|t| t.numel() as i64)
        .sum()
}

const SMALL: ConvNextConfig = ConvNextConfig {
    depths: [1, 1, 2, 1],
    dims: [8, 16, 24, 32],
};

fn small_net_config() -> NetConfig {
    NetConfig {
        encoder: EncoderConfig::Convnext(SMALL),
        psp_branch: 8,
        psp_out: 16,
        decoder: [16, 12, 8],
        descriptor_dim: 6,
        encoder_features: false,
        colour_features: false,
    }
}

#[test]
fn convnext_taps_have_strides_4_to_32() {
    tch::manual_seed(1);
    let vs = nn::VarStore::new(Device::Cpu);
    let encoder = ConvNext::new(&vs.root(), SMALL);
    let taps = encoder.forward(&Tensor::randn([2, 3, 64, 96], (Kind::Float, Device::Cpu)));
    assert_eq!(taps.s4.size(), [2, 8, 16, 24]);
    assert_eq!(taps.s8.size(), [2, 16, 8, 12]);
    assert_eq!(taps.s16.size(), [2, 24, 4, 6]);
    assert_eq!(taps.s32.size(), [2, 32, 2, 3]);
}

#[test]
fn convnext_tiny_and_base_have_the_reference_parameter_counts() {
    // torchvision's convnext_tiny / convnext_base have 28,589,128 and
    // 88,591,464 parameters; without their classifier (LayerNorm 2C + linear
    // C*1000 + 1000) that is the encoder alone.
    for (config, reference, c) in [
        (ConvNextConfig::TINY, 28_589_128i64, 768i64),
        (ConvNextConfig::BASE, 88_591_464, 1024),
    ] {
        let vs = nn::VarStore::new(Device::Cpu);
        let _ = ConvNext::new(&vs.root(), config);
        assert_eq!(parameters(&vs), reference - 2 * c - (c * 1000 + 1000));
    }
}

#[test]
fn mobilenet_v2_matches_torchvision() {
    // torchvision's mobilenet_v2: 3,504,872 parameters.
    let vs = nn::VarStore::new(Device::Cpu);
    let _ = MobileNetV2Classifier::new(&vs.root());
    assert_eq!(parameters(&vs), 3_504_872);
    let names = vs.variables();
    for name in [
        "features.0.0.weight",
        "features.1.conv.0.0.weight",
        "features.1.conv.1.weight",
        "features.2.conv.3.running_var",
        "features.18.1.running_mean",
        "classifier.1.bias",
    ] {
        assert!(names.contains_key(name), "missing {name}");
    }

    let vs = nn::VarStore::new(Device::Cpu);
    let encoder = MobileNetV2::new(&vs.root());
    let taps = encoder.forward_t(
        &Tensor::randn([1, 3, 64, 64], (Kind::Float, Device::Cpu)),
        false,
    );
    assert_eq!(taps.s4.size(), [1, 24, 16, 16]);
    assert_eq!(taps.s8.size(), [1, 32, 8, 8]);
    assert_eq!(taps.s16.size(), [1, 96, 4, 4]);
    assert_eq!(taps.s32.size(), [1, 1280, 2, 2]);
}

#[test]
fn psp_keeps_the_size_and_sets_the_channels() {
    tch::manual_seed(2);
    let vs = nn::VarStore::new(Device::Cpu);
    let psp = Psp::new(&vs.root(), 12, 5, 7);
    for (h, w) in [(7, 7), (1, 1), (3, 10)] {
        let out = psp.forward_t(
            &Tensor::randn([2, 12, h, w], (Kind::Float, Device::Cpu)),
            true,
        );
        assert_eq!(out.size(), [2, 7, h, w]);
    }
}

#[test]
fn decoder_ends_at_stride_4_with_the_last_width() {
    tch::manual_seed(3);
    let vs = nn::VarStore::new(Device::Cpu);
    let encoder = ConvNext::new(&(vs.root() / "e"), SMALL);
    let decoder = Decoder::new(&(vs.root() / "d"), 20, [16, 12, 8], SMALL.dims);
    let taps = encoder.forward(&Tensor::randn([1, 3, 96, 64], (Kind::Float, Device::Cpu)));
    let psp = Tensor::randn([1, 20, 3, 2], (Kind::Float, Device::Cpu));
    assert_eq!(decoder.forward_t(&psp, &taps, false).size(), [1, 8, 24, 16]);
}

#[test]
fn net_gives_unit_descriptors_at_full_resolution() {
    tch::manual_seed(4);
    for config in [
        small_net_config(),
        NetConfig::preset("mobilenet-v2").unwrap(),
    ] {
        let vs = nn::VarStore::new(Device::Cpu);
        let net = MaterialNet::new(&vs.root(), config);
        let x = Tensor::randn([2, 3, 64, 96], (Kind::Float, Device::Cpu));
        for train in [true, false] {
            let y = net.forward_t(&x, train);
            assert_eq!(y.size(), [2, config.descriptor_dim, 64, 96]);
            let norms = y.norm_scalaropt_dim(2, [1], false);
            let max_error = (norms - 1.0).abs().max().double_value(&[]);
            assert!(max_error < 1e-5, "norm off by {max_error}");
        }
    }
}

#[test]
fn encoder_features_join_the_descriptor_weighted_by_learned_factors() {
    tch::manual_seed(5);
    let config = NetConfig {
        encoder_features: true,
        ..small_net_config()
    };
    let vs = nn::VarStore::new(Device::Cpu);
    let net = MaterialNet::new(&vs.root(), config);
    // 6 learned channels, then the taps at strides 4, 8, 16 (8, 16, 24).
    assert_eq!(net.output_dim(), 6 + 8 + 16 + 24);
    let x = Tensor::randn([2, 3, 64, 96], (Kind::Float, Device::Cpu));
    let y = net.forward_t(&x, false);
    assert_eq!(y.size(), [2, 54, 64, 96]);
    let norms = y.norm_scalaropt_dim(2, [1], false);
    assert!((norms - 1.0).abs().max().double_value(&[]) < 1e-5);
    // With the learned part's weight near zero, the descriptor is the
    // encoder's taps alone.
    let mut log_weights = vs.variables()["part_log_weights"].shallow_clone();
    tch::no_grad(|| log_weights.copy_(&Tensor::from_slice(&[-30.0f32, 0.0, 0.0, 0.0])));
    let y = net.forward_t(&x, false);
    let learned = y.narrow(1, 0, 6).abs().max().double_value(&[]);
    assert!(learned < 1e-6, "learned part {learned}");
    let norms = y.norm_scalaropt_dim(2, [1], false);
    assert!((norms - 1.0).abs().max().double_value(&[]) < 1e-5);
    // The weights are variables the optimiser trains.
    assert!(vs.variables()["part_log_weights"].requires_grad());
}

#[test]
fn colour_features_join_the_descriptor_and_follow_the_input_colour() {
    tch::manual_seed(6);
    let config = NetConfig {
        encoder_features: true,
        colour_features: true,
        ..small_net_config()
    };
    let vs = nn::VarStore::new(Device::Cpu);
    let net = MaterialNet::new(&vs.root(), config);
    assert_eq!(net.output_dim(), 6 + 8 + 16 + 24 + COLOUR_FEATURES);
    // Left half one colour, right half another.
    let rgb = Tensor::zeros([1, 3, 64, 64], (Kind::Float, Device::Cpu));
    for (channel, (left, right)) in [(200.0, 30.0), (120.0, 90.0), (40.0, 220.0)]
        .into_iter()
        .enumerate()
    {
        let _ = rgb.get(0).get(channel as i64).narrow(1, 0, 32).fill_(left);
        let _ = rgb
            .get(0)
            .get(channel as i64)
            .narrow(1, 32, 32)
            .fill_(right);
    }
    let y = net.forward_t(&normalise_input(&rgb), false);
    let norms = y.norm_scalaropt_dim(2, [1], false);
    assert!((norms - 1.0).abs().max().double_value(&[]) < 1e-5);
    let colour = y.narrow(1, 54, COLOUR_FEATURES);
    let at = |x: i64| colour.select(3, x).select(2, 30);
    let cosine = |a: &Tensor, b: &Tensor| {
        let (a, b) = (l2_normalise(a, 0), l2_normalise(b, 0));
        (a * b).sum(Kind::Float).double_value(&[])
    };
    // One colour's cells agree; the two colours' barely.
    assert!(cosine(&at(2), &at(20)) > 0.999);
    assert!(cosine(&at(2), &at(60)) < 0.3);
    // The weight and bandwidth are trained, the projection is not.
    let variables = vs.variables();
    assert!(variables["colour.log_weight"].requires_grad());
    assert!(variables["colour.log_bandwidth"].requires_grad());
    assert!(!variables["colour.projection"].requires_grad());
    assert!(!variables["colour.phase"].requires_grad());
}

#[test]
fn presets_follow_the_paper_for_convnext_base() {
    let base = NetConfig::preset("convnext-base").unwrap();
    assert_eq!((base.psp_branch, base.psp_out), (512, 1024));
    assert_eq!(base.decoder, [512, 256, 128]);
    assert_eq!(base.descriptor_dim, 128);
    assert!(NetConfig::preset("resnet-50").is_none());
    let json = serde_json::to_string(&base).unwrap();
    assert_eq!(serde_json::from_str::<NetConfig>(&json).unwrap(), base);
}

#[test]
fn input_is_normalised_as_the_spec_says() {
    let rgb = rgb8_to_tensor(&[0, 255, 124, 200, 100, 50], 2, 1).unsqueeze(0);
    assert_eq!(rgb.size(), [1, 3, 1, 2]);
    let x = normalise_input(&rgb);
    let got = Vec::<f32>::try_from(x.flatten(0, -1)).unwrap();
    let want = [
        (0.0 - 123.68) / 65.0,
        (200.0 - 123.68) / 65.0,
        (255.0 - 116.78) / 65.0,
        (100.0 - 116.78) / 65.0,
        (124.0 - 103.94) / 65.0,
        (50.0 - 103.94) / 65.0,
    ];
    for (g, w) in got.iter().zip(want) {
        assert!((*g as f64 - w).abs() < 1e-6, "{g} vs {w}");
    }
}
