//! The order a run sees a cache's samples in: epoch after epoch, each a
//! shuffle drawn from (seed, epoch), so that step `s`'s samples depend
//! only on the seed and `s` and a resumed run sees the very batches the
//! interrupted one would have.

use matseg_data::sample_rng;
use rand::seq::SliceRandom;

/// Seed offset of the epochs' shuffles.
const EPOCH_STREAM: u64 = 0x6570_6f63_6873_2121;

/// The cache indices of the `images` samples of step `step` from a cache
/// of `samples` samples: positions `step * images ..` in the sequence of
/// epochs, each epoch every sample once in its own shuffled order.
pub fn epoch_indices(samples: u64, images: usize, seed: u64, step: u64) -> Vec<u64> {
    assert!(samples > 0, "a cache with samples");
    let mut order: Option<(u64, Vec<u64>)> = None;
    (0..images as u64)
        .map(|j| {
            let position = step * images as u64 + j;
            let epoch = position / samples;
            if order.as_ref().is_none_or(|(e, _)| *e != epoch) {
                let mut shuffled: Vec<u64> = (0..samples).collect();
                shuffled.shuffle(&mut sample_rng(seed ^ EPOCH_STREAM, epoch));
                order = Some((epoch, shuffled));
            }
            let (_, shuffled) = order.as_ref().expect("drawn above");
            shuffled[(position % samples) as usize]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_epoch_takes_every_sample_once() {
        let (samples, images) = (10, 3);
        let seen: Vec<u64> = (0..10)
            .flat_map(|step| epoch_indices(samples, images, 7, step))
            .collect();
        for epoch in seen.chunks(samples as usize).take(3) {
            let mut sorted = epoch.to_vec();
            sorted.sort();
            assert_eq!(sorted, (0..samples).collect::<Vec<_>>());
        }
        assert_ne!(&seen[..10], &seen[10..20], "epochs are shuffled anew");
        assert_eq!(epoch_indices(samples, images, 7, 4), seen[12..15]);
        assert_ne!(epoch_indices(samples, images, 8, 4), seen[12..15]);
    }
}
