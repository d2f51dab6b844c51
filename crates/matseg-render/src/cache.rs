//! Decoded scene assets shared between the scenes of a process: PBR maps,
//! photo channels, HDRIs with their sampling tables, and meshes, each
//! decoded once. The cache is bounded by a [`MemoryBudget`], its own or the
//! one the process's other caches share: when a new asset would pass it,
//! the cache starts afresh (entries in use by scenes stay alive through
//! their `Arc`s).

use crate::environment::EnvironmentMap;
use crate::mesh::Mesh;
use crate::scene::{LoadedMap, MaterialTextures, SceneError};
use matseg_image::sync::lock;
use matseg_image::{Channel, MemoryBudget};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Default byte budget of an [`AssetCache`].
pub const DEFAULT_CACHE_BYTES: usize = 1 << 30;

/// One kind of cached asset.
type Shelf<K, V> = Mutex<HashMap<K, Arc<V>>>;

/// Assets decoded once per process.
#[derive(Debug)]
pub struct AssetCache {
    budget: Arc<MemoryBudget>,
    /// This cache's part of the budget.
    held: Mutex<usize>,
    materials: Shelf<PathBuf, MaterialTextures>,
    maps: Shelf<(PathBuf, Channel), LoadedMap>,
    hdris: Shelf<PathBuf, EnvironmentMap>,
    meshes: Shelf<PathBuf, Mesh>,
}

impl Drop for AssetCache {
    fn drop(&mut self) {
        self.budget.release(self.held.get_mut().map_or(0, |h| *h));
    }
}

impl Default for AssetCache {
    fn default() -> Self {
        AssetCache::new(DEFAULT_CACHE_BYTES)
    }
}

impl AssetCache {
    /// An empty cache holding at most about `budget` bytes.
    pub fn new(budget: usize) -> Self {
        Self::sharing(MemoryBudget::new(budget))
    }

    /// An empty cache counting its bytes against `budget`, shared with the
    /// process's other caches.
    pub fn sharing(budget: Arc<MemoryBudget>) -> Self {
        AssetCache {
            budget,
            held: Mutex::new(0),
            materials: Mutex::default(),
            maps: Mutex::default(),
            hdris: Mutex::default(),
            meshes: Mutex::default(),
        }
    }

    /// Bytes this cache holds now (approximate).
    pub fn bytes(&self) -> usize {
        *lock(&self.held)
    }

    /// The cached value for `key`, or `load`'s, stored when it fits. Two
    /// threads may decode the same file at once; both get equal values.
    fn get<K, V>(
        &self,
        shelf: &Shelf<K, V>,
        key: K,
        size: impl Fn(&V) -> usize,
        load: impl FnOnce() -> Result<V, SceneError>,
    ) -> Result<Arc<V>, SceneError>
    where
        K: std::hash::Hash + Eq,
    {
        if let Some(v) = lock(shelf).get(&key) {
            return Ok(v.clone());
        }
        let value = Arc::new(load()?);
        let bytes = size(&value);
        let mut held = lock(&self.held);
        if !self.budget.fits(bytes) {
            lock(&self.materials).clear();
            lock(&self.maps).clear();
            lock(&self.hdris).clear();
            lock(&self.meshes).clear();
            self.budget.release(*held);
            *held = 0;
        }
        if bytes <= self.budget.limit() {
            *held += bytes;
            self.budget.add(bytes);
            lock(shelf).insert(key, value.clone());
        }
        Ok(value)
    }

    /// The maps of the PBR material folder `dir`.
    pub fn material(&self, dir: &Path) -> Result<Arc<MaterialTextures>, SceneError> {
        self.get(
            &self.materials,
            dir.to_path_buf(),
            MaterialTextures::bytes,
            || MaterialTextures::read(dir),
        )
    }

    /// Channel `channel` of photo `path`.
    pub fn map(&self, path: &Path, channel: Channel) -> Result<Arc<LoadedMap>, SceneError> {
        self.get(
            &self.maps,
            (path.to_path_buf(), channel),
            |m| m.levels.bytes(),
            || LoadedMap::read(path, channel),
        )
    }

    /// The HDRI `path` with its sampling tables.
    pub fn hdri(&self, path: &Path) -> Result<Arc<EnvironmentMap>, SceneError> {
        self.get(
            &self.hdris,
            path.to_path_buf(),
            EnvironmentMap::bytes,
            || {
                let img = crate::hdr_io::read_hdr(path)?;
                Ok(EnvironmentMap::new(img))
            },
        )
    }

    /// The mesh file `path`.
    pub fn mesh(&self, path: &Path) -> Result<Arc<Mesh>, SceneError> {
        self.get(&self.meshes, path.to_path_buf(), Mesh::bytes, || {
            Ok(crate::mesh_io::read_mesh(path)?)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assets_are_decoded_once_and_the_budget_holds() {
        let photo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/photos/coffee.jpg");
        let cache = AssetCache::default();
        let a = cache.map(&photo, Channel::R).unwrap();
        let b = cache.map(&photo, Channel::R).unwrap();
        assert!(Arc::ptr_eq(&a, &b));
        assert!(!Arc::ptr_eq(&a, &cache.map(&photo, Channel::H).unwrap()));
        assert_eq!(cache.bytes(), 2 * a.levels.bytes());
        let tiny = AssetCache::new(a.levels.bytes() + 10);
        tiny.map(&photo, Channel::R).unwrap();
        tiny.map(&photo, Channel::G).unwrap();
        assert_eq!(
            tiny.bytes(),
            a.levels.bytes(),
            "the second map replaced the first"
        );
        let err = cache
            .map(Path::new("missing.jpg"), Channel::R)
            .unwrap_err()
            .to_string();
        assert!(err.contains("missing.jpg"), "{err}");
    }

    #[test]
    fn a_panic_while_a_shelf_is_held_does_not_stop_the_next_scene() {
        let photo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/photos/coffee.jpg");
        let cache = AssetCache::default();
        let panicked = std::thread::scope(|s| {
            s.spawn(|| {
                let _held = cache.maps.lock();
                let _also = cache.held.lock();
                panic!("a decoder gives up");
            })
            .join()
        });
        assert!(panicked.is_err() && cache.maps.is_poisoned() && cache.held.is_poisoned());
        let map = cache.map(&photo, Channel::R).unwrap();
        assert!(Arc::ptr_eq(&map, &cache.map(&photo, Channel::R).unwrap()));
        assert_eq!(cache.bytes(), map.levels.bytes());
    }

    #[test]
    fn a_shared_budget_counts_what_other_caches_hold() {
        let photo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/photos/coffee.jpg");
        let one = AssetCache::default()
            .map(&photo, Channel::R)
            .unwrap()
            .levels
            .bytes();
        let budget = MemoryBudget::new(2 * one + 10);
        // Another cache of the process holds one map's worth.
        budget.add(one);
        let cache = AssetCache::sharing(budget.clone());
        cache.map(&photo, Channel::R).unwrap();
        assert_eq!(budget.held(), 2 * one);
        // A second map would pass the shared budget: the cache starts afresh.
        cache.map(&photo, Channel::G).unwrap();
        assert_eq!((cache.bytes(), budget.held()), (one, 2 * one));
        drop(cache);
        assert_eq!(budget.held(), one);
    }
}
