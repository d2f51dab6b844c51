//! Texture extraction on images whose uniform regions are known.

use image::RgbImage;
use matseg_extract::textures::{extract_textures, find_squares, TextureOptions};
use rand::{Rng, SeedableRng};
use std::path::Path;

fn texture(name: &str) -> RgbImage {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/textures")
        .join(name);
    image::open(path).unwrap().to_rgb8()
}

fn options() -> TextureOptions {
    TextureOptions {
        cell: 20,
        ..TextureOptions::default()
    }
}

#[test]
fn a_two_texture_mosaic_gives_squares_inside_each_region_only() {
    // Grass on the left; on the right gravel, tinted blue so that the two
    // materials differ in colour as well as in grain. The border is x = 240.
    let (grass, gravel) = (texture("grass.jpg"), texture("gravel.jpg"));
    let mosaic = RgbImage::from_fn(480, 240, |x, y| {
        if x < 240 {
            *grass.get_pixel(x, y)
        } else {
            let [r, g, b] = gravel.get_pixel(x - 240, y).0;
            image::Rgb([r / 3, g / 2, b / 2 + 120])
        }
    });
    let squares = find_squares(&mosaic, &options());
    assert!(!squares.is_empty());
    for s in &squares {
        assert!(s.cells >= 6 && s.side == s.cells * 20);
        assert!(
            s.x + s.side <= 240 || s.x >= 240,
            "{s:?} straddles the border"
        );
        assert!(s.score > 0.5 && s.score <= 1.0);
    }
    assert!(
        squares.iter().any(|s| s.x < 240),
        "nothing found in the grass"
    );
    assert!(
        squares.iter().any(|s| s.x >= 240),
        "nothing found in the gravel"
    );
}

#[test]
fn flat_images_give_no_texture_and_noise_gives_one_large_square() {
    let flat = RgbImage::from_pixel(200, 200, image::Rgb([90, 140, 60]));
    assert!(extract_textures(&flat, &options()).is_empty());

    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let noise = RgbImage::from_fn(200, 200, |_, _| {
        image::Rgb([rng.random(), rng.random(), rng.random()])
    });
    let found = extract_textures(&noise, &options());
    assert_eq!(
        found.len(),
        1,
        "{:?}",
        found.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    let (square, crop) = &found[0];
    assert_eq!((square.x, square.y, square.side), (0, 0, 200));
    assert_eq!(crop.dimensions(), (200, 200));
}
