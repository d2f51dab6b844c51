//! Photos described once: the model's coarse descriptors of each photo a
//! page opened, kept in a cache bounded in bytes (least recently used
//! first out), so every click on a described photo is answered from memory.

use image::RgbImage;
use matseg_image::coarse::CoarseDescriptors;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// A photo and its descriptors.
pub struct Described {
    /// The photo's pixels.
    pub photo: RgbImage,
    /// The model's descriptors of it.
    pub map: CoarseDescriptors,
}

impl Described {
    /// Bytes it holds.
    pub fn bytes(&self) -> usize {
        self.photo.as_raw().len() + 4 * self.map.grid.data.len()
    }
}

/// Described photos by key, at most `budget` bytes of them (the last one
/// always stays, however large).
pub struct DescribedCache {
    budget: usize,
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    entries: HashMap<String, (Arc<Described>, u64)>,
    bytes: usize,
    clock: u64,
}

impl DescribedCache {
    /// An empty cache of at most `budget` bytes.
    pub fn new(budget: usize) -> Self {
        Self {
            budget,
            state: Mutex::default(),
        }
    }

    /// The photo under `key`, if described and still held.
    pub fn get(&self, key: &str) -> Option<Arc<Described>> {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        state.clock += 1;
        let now = state.clock;
        state.entries.get_mut(key).map(|(d, used)| {
            *used = now;
            d.clone()
        })
    }

    /// Keeps `described` under `key`, letting the least recently used go
    /// while the budget is passed.
    pub fn insert(&self, key: &str, described: Arc<Described>) {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        state.clock += 1;
        let now = state.clock;
        let bytes = described.bytes();
        if let Some((old, _)) = state.entries.insert(key.to_string(), (described, now)) {
            state.bytes -= old.bytes();
        }
        state.bytes += bytes;
        while state.bytes > self.budget && state.entries.len() > 1 {
            let oldest = state
                .entries
                .iter()
                .min_by_key(|(_, (_, used))| *used)
                .map(|(k, _)| k.clone())
                .expect("non-empty");
            if let Some((old, _)) = state.entries.remove(&oldest) {
                state.bytes -= old.bytes();
            }
        }
    }

    /// Bytes held now.
    pub fn bytes(&self) -> usize {
        self.state.lock().unwrap_or_else(|e| e.into_inner()).bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use matseg_image::descriptor::DescriptorMap;

    fn described(side: u32) -> Arc<Described> {
        let s = side as usize;
        Arc::new(Described {
            photo: RgbImage::new(side, side),
            map: CoarseDescriptors {
                grid: DescriptorMap {
                    width: s,
                    height: s,
                    dim: 1,
                    data: vec![1.0; s * s],
                },
                width: s,
                height: s,
            },
        })
    }

    #[test]
    fn the_cache_keeps_within_its_budget_least_recently_used_first_out() {
        let one = described(10).bytes();
        let cache = DescribedCache::new(2 * one);
        cache.insert("a", described(10));
        cache.insert("b", described(10));
        assert!(cache.get("a").is_some());
        cache.insert("c", described(10));
        assert_eq!(cache.bytes(), 2 * one);
        assert!(cache.get("b").is_none(), "b was the least recently used");
        assert!(cache.get("a").is_some() && cache.get("c").is_some());
        // One photo larger than the budget still stays.
        cache.insert("big", described(40));
        assert!(cache.get("big").is_some());
        assert_eq!(cache.bytes(), described(40).bytes());
    }
}
