//! Soft-map invariants over many seeds, on the bundled photos.

use matseg_extract::{combine_maps, draw_channel_map, MapNormalisation, RawMap, SoftMapRecipe};
use matseg_image::{level_values, Channel, ChannelWindow, Coverage, PhotoLibrary, Plane};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;

fn photos() -> PhotoLibrary {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/photos");
    PhotoLibrary::scan(&[dir], 1 << 30).unwrap().0
}

#[test]
fn maps_match_their_record_and_acceptance_rules() {
    let lib = photos();
    let recipe = SoftMapRecipe::default();
    let mut ramps = 0;
    for seed in 0..60u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (w, h) = (96 + (seed as usize % 5) * 17, 80 + (seed as usize % 3) * 23);
        let max_occupancy = 0.04 + 0.5 * (seed % 7) as f64 / 7.0;
        let hard = seed % 3 == 0;
        let (raw, rec) =
            draw_channel_map(&mut rng, &lib, w, h, max_occupancy, hard, &recipe).unwrap();
        let map = raw.to_plane();
        assert_eq!((map.width, map.height), (w, h));
        assert_eq!(raw.coverage(), &Coverage::of(&map));

        // Re-derive the channel from the record: the map must be the ramp of it.
        let photo = lib.get(rec.photo).unwrap();
        let window = photo
            .pyramid
            .sample_channel(&rec.placement, w, h, rec.channel);
        let top = *window.levels.iter().max().unwrap();
        let divisor = if rec.normalised_by_max { top } else { 255 };
        let channel = window.map_levels(&level_values(divisor));
        let (lo, hi) = (rec.ramp.low, rec.ramp.high);
        assert!((0.0..=1.0).contains(&lo) && lo <= hi && hi <= 1.0);
        for (&c, &m) in channel.data.iter().zip(&map.data) {
            if c > hi {
                assert_eq!(m, 1.0);
            } else if c <= lo {
                assert_eq!(m, 0.0);
            } else {
                assert!((m - (c - lo) / (hi - lo)).abs() < 1e-5);
            }
        }

        // Acceptance: the top side holds (1%, max_occupancy] of the pixels;
        // a ramp has > 1% below it and a band under a third of either side.
        let n = channel.len() as f64;
        let above = channel.count_above(hi) as f64;
        assert!(
            above > 0.01 * n && above <= max_occupancy * n,
            "seed {seed}: {above} of {n}"
        );
        if lo < hi {
            ramps += 1;
            assert!(!hard, "hard scenes use binary maps");
            let below = channel.count_at_or_below(lo) as f64;
            let band = n - above - below;
            assert!(below > 0.01 * n);
            assert!(band < above.min(below) / 3.0);
        }
        assert!(map.sum() >= recipe.min_map_mass);
    }
    assert!(ramps > 5, "soft ramps should occur ({ramps})");
}

/// A map whose pixel `i` has level `level(i)`, worth `level / top`.
fn map(w: usize, h: usize, top: u8, level: impl Fn(usize) -> u8) -> RawMap {
    let window = ChannelWindow {
        width: w,
        height: h,
        channel: Channel::R,
        levels: (0..w * h).map(level).collect(),
    };
    RawMap::new(window, level_values(top))
}

#[test]
fn combined_weights_sum_to_one_and_hard_is_one_hot() {
    let (w, h) = (40, 30);
    let maps = vec![
        map(w, h, 6, |i| (i % 7) as u8),
        map(w, h, 4, |i| ((i / 3) % 5) as u8),
        map(w, h, 1, |i| u8::from(i % 11 == 0)),
    ];
    let mut seen = [false; 2];
    for seed in 0..40u64 {
        for hard in [false, true] {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let combined = combine_maps(&mut rng, maps.clone(), hard, &SoftMapRecipe::default());
            let weights: Vec<Plane> = combined.weights.iter().map(|w| w.to_plane()).collect();
            let (bg, rec) = (&combined.background, &combined.record);
            for (w, c) in weights.iter().zip(&combined.coverage) {
                assert_eq!(c, &Coverage::of(w), "coverage built with the weights");
            }
            seen[(rec.normalisation == MapNormalisation::Sum) as usize] = true;
            assert_eq!(weights.len(), 3);
            for i in 0..w * h {
                let total: f32 = weights.iter().map(|m| m.data[i]).sum::<f32>() + bg.data[i];
                assert!((total - 1.0).abs() < 1e-5, "pixel {i} sums to {total}");
                assert!(weights.iter().all(|m| (0.0..=1.0).contains(&m.data[i])));
                if hard {
                    let ones = weights.iter().filter(|m| m.data[i] == 1.0).count();
                    let zeros = weights.iter().filter(|m| m.data[i] == 0.0).count();
                    assert_eq!(ones + zeros, 3);
                    assert!(ones <= 1);
                }
            }
            if !hard && rec.normalisation == MapNormalisation::Priority && rec.blur_kernel.is_none()
            {
                // Priority: the first map keeps its raw values.
                assert_eq!(weights[0].data, maps[0].to_plane().data);
            }
        }
    }
    assert!(seen[0] && seen[1], "both normalisations should be drawn");
}
