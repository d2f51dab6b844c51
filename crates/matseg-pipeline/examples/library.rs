//! The library in one page (docs/library.md): generate 10 scenes, train a
//! net on them for 5 steps, and segment a photo with it.
//! `cargo run --release -p matseg-pipeline --features net --example library -- OUT`

use matseg_data::{generate_dataset, GenerateOptions};
use matseg_image::{device::ComputeDevice, io::read_rgb, progress::Silent, LicenceFilter};
use matseg_pipeline::segment::{describe, load_model, write_point_maps, DEFAULT_RADIUS};
use matseg_pipeline::select::MaterialClicks;
use matseg_pipeline::sources::{assets_dir, Defaults, Libraries};
use matseg_pipeline::train::{start, TrainConfig, TrainData, TrainInputs};
use matseg_scene::Recipe2d;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or("library-out".into()));
    let libraries = Libraries::load(&[], &[], 512, Defaults::Bundled, &LicenceFilter::parse("")?)?;
    // 10 synthetic scenes with exact soft annotations.
    let data = out.join("data");
    let scenes = GenerateOptions::folders(&data, 10, 0);
    generate_dataset(&scenes, &Recipe2d::default(), libraries.sources(), &Silent)?;
    // A net trained on them for 5 steps (from scratch: nothing to fetch).
    let config = TrainConfig::new(out.join("run"), TrainData::Dataset(data));
    let config = TrainConfig {
        steps: 5,
        init: "scratch".into(),
        ..config
    };
    let mut run = start(&config, ComputeDevice::Cpu)?;
    run.train(&TrainInputs::new(&libraries), |m| {
        println!("step {}: loss {:?}", m.step, m.loss)
    })?;
    // Where else in the photo is the material under this point?
    let model = load_model(&run.model_file(), ComputeDevice::Cpu)?;
    let photo = read_rgb(&assets_dir().join("photos/coffee.jpg"))?;
    let map = describe(&model, &photo);
    let clicks = MaterialClicks::group(&[(None, (290.0, 130.0))], Vec::new());
    let model_file = run.model_file().display().to_string();
    write_point_maps(
        &photo,
        &map,
        &clicks,
        DEFAULT_RADIUS,
        &model_file,
        &out.join("segment"),
    )?;
    println!(
        "{}: similarity map, overlay and the selection's mask",
        out.join("segment").display()
    );
    Ok(())
}
