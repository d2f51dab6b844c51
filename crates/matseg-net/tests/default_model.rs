//! The shipped default model (`models/default`) loads by name, gives unit
//! descriptors, and tells materials of a bundled photo apart: two points on
//! one material are more alike than points on two materials.

use matseg_image::device::ComputeDevice;
use matseg_net::infer::{default_model_dir, NetModel, DEFAULT_MODEL};
use matseg_query::descriptor::{Comparison, DescriptorModel};
use std::path::Path;

#[test]
fn the_default_model_separates_the_materials_of_a_bundled_photo() {
    assert!(
        default_model_dir().is_some(),
        "models/default is missing from the checkout"
    );
    let model = NetModel::load(Path::new(DEFAULT_MODEL), ComputeDevice::Cpu).unwrap();
    assert_eq!(model.name(), "default");
    let photo =
        image::open(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/photos/coffee.jpg"))
            .unwrap()
            .to_rgb8();
    let map = model.describe(&photo);
    assert_eq!((map.width, map.height), (600, 400));
    for i in (0..map.width * map.height).step_by(997) {
        let n: f32 = map.at(i).iter().map(|v| v * v).sum();
        assert!((n - 1.0).abs() < 1e-3, "pixel {i}: |d|^2 = {n}");
    }
    let point = |x: f32, y: f32| map.point_descriptor(x, y, 6.0, Comparison::Cosine);
    let sim = |a: &[f32], b: &[f32]| Comparison::Cosine.similarity(a, b);
    // The wooden table, the red saucer and the coffee's crema.
    let (wood, wood_too) = (point(530.0, 200.0), point(560.0, 350.0));
    let (saucer, saucer_too) = (point(120.0, 250.0), point(440.0, 250.0));
    let (crema, crema_too) = (point(270.0, 140.0), point(320.0, 165.0));
    for (a, b, others) in [
        (&wood, &wood_too, [&saucer, &crema]),
        (&saucer, &saucer_too, [&wood, &crema]),
        (&crema, &crema_too, [&wood, &saucer]),
    ] {
        let same = sim(a, b);
        for other in others {
            assert!(
                same > sim(a, other),
                "same {same}, across {}",
                sim(a, other)
            );
        }
    }
}
