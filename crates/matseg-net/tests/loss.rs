//! The MatSeg loss against hand-computed cases and its gradient against
//! finite differences.

use matseg_net::blocks::l2_normalise;
use matseg_net::{matseg_loss, ImageTargets, TEMPERATURE};
use tch::{Device, Kind, Tensor};

const F64: (Kind, Device) = (Kind::Double, Device::Cpu);

/// `[D, H, W]` from per-pixel descriptors (pixels in row-major order).
fn descriptors(pixels: &[[f64; 2]], h: i64, w: i64) -> Tensor {
    let flat: Vec<f64> = (0..2)
        .flat_map(|c| pixels.iter().map(move |p| p[c]))
        .collect();
    Tensor::from_slice(&flat).view([2, h, w])
}

fn targets(weights: &[&[f64]], roi: &[f64], h: i64, w: i64) -> ImageTargets {
    let flat: Vec<f64> = weights.iter().flat_map(|m| m.iter().copied()).collect();
    ImageTargets {
        weights: Tensor::from_slice(&flat).view([weights.len() as i64, h, w]),
        roi: Tensor::from_slice(roi).view([h, w]),
    }
}

/// `-log softmax(cos / T)` of a pixel against material cosines, with soft targets.
fn pixel_loss(cosines: &[f64], targets: &[f64]) -> f64 {
    let logits: Vec<f64> = cosines.iter().map(|c| c / TEMPERATURE).collect();
    let log_sum = logits.iter().map(|l| l.exp()).sum::<f64>().ln();
    -targets
        .iter()
        .zip(&logits)
        .map(|(t, l)| t * (l - log_sum))
        .sum::<f64>()
}

#[test]
fn one_image_two_materials_by_hand() {
    // Pixels (1,0), (0,1), (0.6,0.8); material A owns pixel 0 (weight 1)
    // and 0.3 of pixel 2, B owns pixel 1 and 0.7 of pixel 2.
    let d = descriptors(&[[1.0, 0.0], [0.0, 1.0], [0.6, 0.8]], 1, 3);
    let t = targets(
        &[&[1.0, 0.0, 0.3], &[0.0, 1.0, 0.7]],
        &[1.0, 1.0, 1.0],
        1,
        3,
    );
    let loss = matseg_loss(&d.unsqueeze(0), &[t])
        .unwrap()
        .double_value(&[]);

    // A's region is pixel 0 alone: descriptor (1, 0). B's region is pixels 1
    // and 2: mean (0.3, 0.9), normalised (1, 3) / sqrt(10).
    let b = [1.0 / 10f64.sqrt(), 3.0 / 10f64.sqrt()];
    let expected = (pixel_loss(&[1.0, b[0]], &[1.0, 0.0])
        + pixel_loss(&[0.0, b[1]], &[0.0, 1.0])
        + pixel_loss(&[0.6, 0.6 * b[0] + 0.8 * b[1]], &[0.3, 0.7]))
        / 3.0;
    assert!((loss - expected).abs() < 1e-12, "{loss} vs {expected}");
}

#[test]
fn roi_masks_pixels_and_other_images_materials_are_negatives() {
    // Two images of one material each: each is the other's negative. The
    // second image's pixel 1 is outside the ROI.
    let d1 = descriptors(&[[1.0, 0.0], [0.8, 0.6]], 1, 2);
    let d2 = descriptors(&[[0.0, 1.0], [1.0, 0.0]], 1, 2);
    let t1 = targets(&[&[1.0, 1.0]], &[1.0, 1.0], 1, 2);
    let t2 = targets(&[&[1.0, 0.9]], &[1.0, 0.0], 1, 2);
    let batch = Tensor::stack(&[d1, d2], 0);
    let loss = matseg_loss(&batch, &[t1, t2]).unwrap().double_value(&[]);

    let m1 = [0.9 / 0.9f64.hypot(0.3), 0.3 / 0.9f64.hypot(0.3)];
    let m2 = [0.5f64.sqrt(), 0.5f64.sqrt()];
    let cos = |p: [f64; 2], m: [f64; 2]| p[0] * m[0] + p[1] * m[1];
    let expected = (pixel_loss(&[cos([1.0, 0.0], m1), cos([1.0, 0.0], m2)], &[1.0, 0.0])
        + pixel_loss(&[cos([0.8, 0.6], m1), cos([0.8, 0.6], m2)], &[1.0, 0.0])
        + pixel_loss(&[cos([0.0, 1.0], m1), cos([0.0, 1.0], m2)], &[0.0, 1.0]))
        / 4.0;
    assert!((loss - expected).abs() < 1e-12, "{loss} vs {expected}");
}

#[test]
fn fewer_than_two_materials_give_no_loss() {
    let d = descriptors(&[[1.0, 0.0], [0.0, 1.0]], 1, 2);
    // One material with a region; the other never exceeds 0.5.
    let t = targets(&[&[0.6, 0.6], &[0.4, 0.4]], &[1.0, 1.0], 1, 2);
    assert!(matseg_loss(&d.unsqueeze(0), &[t]).is_none());
}

#[test]
fn gradient_matches_finite_differences() {
    tch::manual_seed(7);
    let (b, d, h, w) = (2, 4, 3, 3);
    let raw = Tensor::randn([b, d, h, w], F64);
    let soft = |k: i64| Tensor::rand([k, h, w], F64).softmax(0, Kind::Double);
    let targets = || {
        vec![
            ImageTargets {
                weights: soft(2),
                roi: Tensor::ones([h, w], F64),
            },
            ImageTargets {
                weights: soft(3),
                roi: Tensor::rand([h, w], F64).gt(0.3).to_kind(Kind::Double),
            },
        ]
    };
    let targets = targets();
    let loss_of = |x: &Tensor| matseg_loss(&l2_normalise(x, 1), &targets).unwrap();

    let x = raw.copy().set_requires_grad(true);
    loss_of(&x).backward();
    let analytic = Vec::<f64>::try_from(x.grad().flatten(0, -1)).unwrap();

    let eps = 1e-6;
    let base = Vec::<f64>::try_from(raw.flatten(0, -1)).unwrap();
    let mut worst = 0f64;
    for i in 0..base.len() {
        let shifted = |delta: f64| {
            let mut v = base.clone();
            v[i] += delta;
            loss_of(&Tensor::from_slice(&v).view([b, d, h, w])).double_value(&[])
        };
        let numeric = (shifted(eps) - shifted(-eps)) / (2.0 * eps);
        worst = worst.max((numeric - analytic[i]).abs());
    }
    let scale = analytic.iter().fold(0f64, |m, g| m.max(g.abs()));
    assert!(scale > 1e-3, "gradient too small to test: {scale}");
    assert!(
        worst < 1e-7 * scale.max(1.0) * 100.0,
        "worst difference {worst} (scale {scale})"
    );
}
