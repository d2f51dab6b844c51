use matseg_data::sample_rng;
use matseg_image::PhotoLibrary;
use matseg_scene::{generate_2d, Recipe2d, Sources};
use std::path::Path;
fn main() {
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
    let recipe = Recipe2d::default();
    let n: u64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(200);
    for i in 0..16 {
        generate_2d(&mut sample_rng(0xdead, i), &recipe, sources).unwrap();
    }
    let t = std::time::Instant::now();
    for r in 0..n {
        generate_2d(&mut sample_rng(1, r % 40), &recipe, sources).unwrap();
    }
    eprintln!("{:.4} s/scene", t.elapsed().as_secs_f64() / n as f64);
}
