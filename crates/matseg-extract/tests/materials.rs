//! Material folders in every naming read back to the same maps.

use image::{GrayImage, RgbImage};
use matseg_extract::material_library::{find_materials, read_material};
use matseg_extract::pbr::{make_pbr, PbrRecipe};
use rand::SeedableRng;
use std::path::Path;

fn colour() -> RgbImage {
    RgbImage::from_fn(8, 6, |x, y| image::Rgb([x as u8 * 30, y as u8 * 40, 77]))
}

fn grey(v: u8) -> GrayImage {
    GrayImage::from_pixel(8, 6, image::Luma([v]))
}

fn save(dir: &Path, files: &[(&str, u8)]) {
    std::fs::create_dir_all(dir).unwrap();
    for (name, v) in files {
        if *v == 0 {
            colour().save(dir.join(name)).unwrap();
        } else {
            grey(*v).save(dir.join(name)).unwrap();
        }
    }
}

#[test]
fn ambientcg_matseg_and_matsynth_folders_read_alike() {
    let root = tempfile::tempdir().unwrap();
    let (cg, ms, synth) = (
        root.path().join("cg/Rock"),
        root.path().join("matseg/a"),
        root.path().join("synth/b"),
    );
    save(
        &cg,
        &[
            ("Rock_1K_Color.png", 0),
            ("Rock_1K_Roughness.png", 10),
            ("Rock_1K_Metalness.png", 20),
            ("Rock_1K_Displacement.png", 30),
        ],
    );
    save(
        &ms,
        &[
            ("OriginColor.png", 0),
            ("Roughness.png", 10),
            ("Metallic.png", 20),
            ("Height.png", 30),
        ],
    );
    save(
        &synth,
        &[
            ("basecolor.png", 0),
            ("roughness.png", 10),
            ("metallic.png", 20),
            ("height.png", 30),
        ],
    );
    // A DirectX normal map: green is flipped on reading.
    RgbImage::from_pixel(8, 6, image::Rgb([128, 200, 255]))
        .save(cg.join("Rock_1K_NormalDX.png"))
        .unwrap();
    std::fs::write(root.path().join("cg/readme.txt"), "not a material").unwrap();

    let found = find_materials(root.path()).unwrap();
    assert_eq!(found, [cg.clone(), ms.clone(), synth.clone()]);
    for dir in &found {
        let m = read_material(dir).unwrap();
        assert_eq!(m.colour, colour());
        assert_eq!(m.roughness, Some(grey(10)));
        assert_eq!(m.metalness, Some(grey(20)));
        assert_eq!(m.height, Some(grey(30)));
    }
    assert_eq!(
        read_material(&cg)
            .unwrap()
            .normal
            .unwrap()
            .get_pixel(0, 0)
            .0,
        [128, 55, 255]
    );
    std::fs::remove_file(ms.join("OriginColor.png")).unwrap();
    assert!(read_material(&ms)
        .unwrap_err()
        .to_string()
        .contains("no colour map"));
}

#[test]
fn our_pbr_output_reads_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let m = make_pbr(
        &mut rand_chacha::ChaCha8Rng::seed_from_u64(2),
        &colour(),
        &PbrRecipe::default(),
    );
    m.write_maps(dir.path()).unwrap();
    let back = read_material(dir.path()).unwrap();
    assert_eq!(back.colour, m.colour);
    assert_eq!(back.normal.as_ref(), Some(&m.normal));
    let by_kind = |k: usize| Some(m.maps[k].1.clone());
    assert_eq!(back.height, by_kind(0));
    assert_eq!(back.roughness, by_kind(1));
    assert_eq!(back.metalness, by_kind(2));
    assert_eq!(back.ambient_occlusion, by_kind(3));
    assert_eq!(back.opacity, by_kind(4));
    assert_eq!(back.specular, by_kind(5));
}
