//! What the server keeps in memory of the photos the model described:
//! their pixels and coarse descriptors, so every click on a described
//! photo is answered from memory, within one byte budget, least recently
//! used first out. A description is counted against the budget before it
//! is made ([`DescribedCache::reserve`]), and a photo of more than
//! [`MAX_DESCRIBED_PIXELS`] is described shrunk to that many, so that
//! neither the photos kept nor the one being described can pass the
//! budget by more than one capped description, however large the photo.
//! Clicks and answers stay in the photo's own pixels.

use crate::app::ApiError;
use axum::http::StatusCode;
use image::RgbImage;
use matseg_image::MemoryBudget;
use matseg_query::coarse::CoarseDescriptors;
use matseg_query::select::PhotoPrep;
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// The most pixels a photo is described at (2048 x 2048): a larger one
/// is shrunk to this many, keeping its proportions. The model sees at most
/// its largest inference side (700 pixels for the shipped one) either
/// way; what the photo's own pixels add past this (the selection's edges
/// and colours) is finer than a click can tell apart.
pub const MAX_DESCRIBED_PIXELS: u64 = 2048 * 2048;

/// The size a `width x height` photo is described at: its own up to
/// [`MAX_DESCRIBED_PIXELS`], else shrunk to fit that many pixels, keeping
/// its proportions (each side one pixel at least).
pub fn described_size(width: u32, height: u32) -> (u32, u32) {
    let pixels = width as u64 * height as u64;
    if pixels <= MAX_DESCRIBED_PIXELS {
        return (width, height);
    }
    let scale = (MAX_DESCRIBED_PIXELS as f64 / pixels as f64).sqrt();
    let fit = |side: u32| ((side as f64 * scale).floor() as u32).clamp(1, side);
    let (mut w, mut h) = (fit(width), fit(height));
    // A side held at one pixel can leave the other over the cap.
    while w as u64 * h as u64 > MAX_DESCRIBED_PIXELS {
        if w >= h {
            w -= 1;
        } else {
            h -= 1;
        }
    }
    (w, h)
}

/// A photo, its descriptors, and what its selections prepared of it.
pub struct Described {
    /// The photo's pixels as described: the photo itself, or shrunk to
    /// [`described_size`] when it has more than [`MAX_DESCRIBED_PIXELS`].
    pub photo: RgbImage,
    /// The model's descriptors of it.
    pub map: CoarseDescriptors,
    /// Shared by every selection on the photo, made with the photo's
    /// description so that no click waits for it.
    pub prep: Arc<PhotoPrep>,
    /// The photo's own width: clicks and answers are in its pixels.
    pub width: u32,
    /// The photo's own height.
    pub height: u32,
}

impl Described {
    /// `photo` (as described) and its descriptors `map`, with the
    /// preparation of its selections; `size` is the photo's own.
    pub fn new(photo: RgbImage, map: CoarseDescriptors, size: (u32, u32)) -> Self {
        let prep = PhotoPrep::default();
        prep.prepare(&map, Some(&photo));
        Self {
            photo,
            map,
            prep: Arc::new(prep),
            width: size.0,
            height: size.1,
        }
    }

    /// Bytes it holds, its selections' preparation counted at its most.
    pub fn bytes(&self) -> usize {
        let grid = &self.map.grid;
        bytes_held(self.photo.dimensions(), grid.width * grid.height, grid.dim)
    }

    /// Whether the photo was described shrunk.
    pub fn shrunk(&self) -> bool {
        self.photo.dimensions() != (self.width, self.height)
    }

    /// A point in the photo's pixels, where it lies on the photo as
    /// described (the point itself when it was not shrunk).
    pub fn point(&self, x: f32, y: f32) -> (f32, f32) {
        if !self.shrunk() {
            return (x, y);
        }
        let (w, h) = self.photo.dimensions();
        let (sx, sy) = self.scale();
        // Inside the photo stays inside, rounding aside.
        let below = |side: u32| side as f32 - 1e-3;
        ((x * sx).min(below(w)), (y * sy).min(below(h)))
    }

    /// A disc radius in the photo's pixels, in the pixels it was described
    /// at.
    pub fn radius(&self, radius: f32) -> f32 {
        if !self.shrunk() {
            return radius;
        }
        let (sx, sy) = self.scale();
        radius * (sx + sy) / 2.0
    }

    /// Described pixels per photo pixel, across and down.
    fn scale(&self) -> (f32, f32) {
        let (w, h) = self.photo.dimensions();
        (w as f32 / self.width as f32, h as f32 / self.height as f32)
    }

    /// Values of each pixel of the photo as described (`channels` bytes a
    /// pixel, row by row) at the photo's own size, each pixel taking the
    /// value of the described pixel it lies in; `values` as they are when
    /// the photo was not shrunk.
    pub fn at_photo_size(&self, values: Vec<u8>, channels: usize) -> Vec<u8> {
        if !self.shrunk() {
            return values;
        }
        let (w, h) = self.photo.dimensions();
        let (w, h) = (w as usize, h as usize);
        let (width, height) = (self.width as usize, self.height as usize);
        // The described pixel under each photo pixel's centre.
        let nearest = |i: usize, own: usize, described: usize| {
            ((2 * i + 1) * described / (2 * own)).min(described - 1)
        };
        let columns: Vec<usize> = (0..width).map(|x| nearest(x, width, w)).collect();
        let row_bytes = width * channels;
        let mut out = Vec::with_capacity(row_bytes * height);
        let mut previous = None;
        for y in 0..height {
            let source = nearest(y, height, h);
            if previous == Some(source) {
                let start = out.len() - row_bytes;
                out.extend_from_within(start..);
                continue;
            }
            let row = &values[source * w * channels..(source + 1) * w * channels];
            for &x in &columns {
                out.extend_from_slice(&row[x * channels..(x + 1) * channels]);
            }
            previous = Some(source);
        }
        out
    }
}

/// The bytes a description of a photo described at `size` holds, with
/// `cells` grid cells of `dim` values: its pixels, its descriptors and
/// its selections' preparation at its most.
pub fn bytes_held(size: (u32, u32), cells: usize, dim: usize) -> usize {
    let (w, h) = (size.0 as usize, size.1 as usize);
    3 * w * h + 4 * cells * dim + PhotoPrep::bytes_at_most(w, h, cells, dim)
}

/// Described photos by key (root and file), within a byte budget, least
/// recently used first out; descriptions under way are counted in it
/// before they are made.
pub struct DescribedCache {
    budget: Arc<MemoryBudget>,
    state: Mutex<CacheState>,
}

struct CacheState {
    /// Value, its bytes, when it was last used.
    entries: HashMap<String, (Arc<Described>, usize, u64)>,
    /// Bytes the entries hold.
    bytes: usize,
    /// Counts uses.
    clock: u64,
}

/// A description under way, counted against the cache's budget until it
/// is kept ([`Reservation::keep`]) or dropped.
pub struct Reservation<'a> {
    cache: &'a DescribedCache,
    bytes: usize,
}

impl DescribedCache {
    /// An empty cache counting against `budget`.
    pub fn new(budget: Arc<MemoryBudget>) -> Self {
        Self {
            budget,
            state: Mutex::new(CacheState {
                entries: HashMap::new(),
                bytes: 0,
                clock: 0,
            }),
        }
    }

    fn state(&self) -> std::sync::MutexGuard<'_, CacheState> {
        matseg_image::sync::lock(&self.state)
    }

    /// The photo described under `key`, if kept.
    pub fn get(&self, key: &str) -> Option<Arc<Described>> {
        let mut state = self.state();
        state.clock += 1;
        let now = state.clock;
        state.entries.get_mut(key).map(|(value, _, used)| {
            *used = now;
            value.clone()
        })
    }

    /// Bytes the described photos kept hold (not those under way).
    pub fn bytes(&self) -> usize {
        self.state().bytes
    }

    /// How many described photos are kept.
    pub fn len(&self) -> usize {
        self.state().entries.len()
    }

    /// Whether none is kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Counts `bytes` of a description about to be made against the
    /// budget, letting the least recently used photos go while the budget
    /// would be passed (all of them, if need be: the new one comes in
    /// their place).
    pub fn reserve(&self, bytes: usize) -> Reservation<'_> {
        let mut state = self.state();
        while !self.budget.fits(bytes) && self.evict_oldest(&mut state) {}
        self.budget.add(bytes);
        Reservation { cache: self, bytes }
    }

    /// Lets the least recently used photo go; false when none is kept.
    fn evict_oldest(&self, state: &mut CacheState) -> bool {
        let oldest = state
            .entries
            .iter()
            .min_by_key(|(_, (_, _, used))| *used)
            .map(|(k, _)| k.clone());
        let Some((_, bytes, _)) = oldest.and_then(|k| state.entries.remove(&k)) else {
            return false;
        };
        state.bytes -= bytes;
        self.budget.release(bytes);
        true
    }
}

impl Reservation<'_> {
    /// Keeps `value` under `key`, counted with the bytes it holds in place
    /// of those reserved; the least recently used others go while the
    /// budget is passed.
    pub fn keep(self, key: String, value: Arc<Described>) {
        let cache = self.cache;
        let bytes = value.bytes();
        let mut state = cache.state();
        state.clock += 1;
        let now = state.clock;
        cache.budget.add(bytes);
        if let Some((_, old, _)) = state.entries.insert(key.clone(), (value, bytes, now)) {
            state.bytes -= old;
            cache.budget.release(old);
        }
        state.bytes += bytes;
        // Released with the state held, so that no other reservation
        // sees the bytes twice or not at all.
        drop(self);
        while cache.budget.exceeded() && state.entries.len() > 1 {
            let newest = state.entries.remove(&key);
            cache.evict_oldest(&mut state);
            if let Some(entry) = newest {
                state.entries.insert(key.clone(), entry);
            }
        }
    }
}

impl Drop for Reservation<'_> {
    fn drop(&mut self) {
        self.cache.budget.release(self.bytes);
    }
}

impl Drop for DescribedCache {
    fn drop(&mut self) {
        let held = self.state.get_mut().map_or(0, |s| s.bytes);
        self.budget.release(held);
    }
}

/// How many pieces of work on a photo's full pixels (decoding it to check
/// an upload or to describe it, describing it, an answer at its own size
/// when it was described shrunk) run at once: each can need some hundred
/// MiB for a 40-megapixel photo, so they take turns.
pub const PHOTO_WORK_AT_ONCE: usize = 1;

/// How many more may wait for their turn; past that a request is refused
/// (503) rather than queued without end.
pub const PHOTO_WORK_WAITING: usize = 16;

/// Turns at the work on a photo's full pixels: [`PHOTO_WORK_AT_ONCE`] at
/// a time, [`PHOTO_WORK_WAITING`] more waiting.
pub struct PhotoWork {
    permits: Arc<tokio::sync::Semaphore>,
    waiting: Arc<AtomicUsize>,
}

impl Default for PhotoWork {
    fn default() -> Self {
        Self {
            permits: Arc::new(tokio::sync::Semaphore::new(PHOTO_WORK_AT_ONCE)),
            waiting: Arc::default(),
        }
    }
}

/// A turn at the work on a photo's full pixels, until dropped.
pub type Turn = tokio::sync::OwnedSemaphorePermit;

impl PhotoWork {
    /// Waits for a turn; a 503 naming `what` when too many wait already.
    pub async fn turn(&self, what: &str) -> Result<Turn, ApiError> {
        if let Ok(turn) = self.permits.clone().try_acquire_owned() {
            return Ok(turn);
        }
        let waiting = self.waiting.fetch_add(1, Ordering::SeqCst);
        // Counted out however the wait ends (the request may be dropped).
        let _counted = Waiting(self.waiting.clone());
        if waiting >= PHOTO_WORK_WAITING {
            return Err(ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                format!(
                    "{what}: {waiting} photos are waiting to be read or described; try again when they are done"
                ),
            ));
        }
        self.permits
            .clone()
            .acquire_owned()
            .await
            .map_err(|e| ApiError::internal(e.to_string()))
    }

    /// How many requests wait for a turn now.
    pub fn waiting(&self) -> usize {
        self.waiting.load(Ordering::SeqCst)
    }
}

/// One request counted as waiting, until dropped.
struct Waiting(Arc<AtomicUsize>);

impl Drop for Waiting {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// The size from which an allocation is mapped on its own (and unmapped
/// when freed) rather than taken from the heap: see
/// [`map_large_allocations`].
pub const MAPPED_FROM_BYTES: usize = 8 << 20;

/// How much free memory the top of the heap may keep before it is given
/// back: see [`map_large_allocations`].
pub const KEPT_AT_HEAP_TOP_BYTES: usize = 64 << 20;

/// Has every allocation of [`MAPPED_FROM_BYTES`] or more mapped on its own
/// from now on, given back to the system as soon as it is freed, and the
/// top of the heap keep up to [`KEPT_AT_HEAP_TOP_BYTES`] free (glibc:
/// `M_MMAP_THRESHOLD` and `M_TRIM_THRESHOLD`; elsewhere nothing): what the
/// server does when it starts. The model's pass over a photo allocates and
/// frees tensors of tens of MiB one after another; taken from the heap
/// (the allocator's default once a large block has been freed), the
/// blocks freed stay resident until the pass ends, and four large photos
/// described in a row took the server's peak memory some 200 MiB higher
/// (BENCHMARKS.md). The heap's top is kept so that the smaller blocks of
/// clicks are not given back and faulted in again at every click.
pub fn map_large_allocations() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes settings of the allocator.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MAPPED_FROM_BYTES as libc::c_int);
        libc::mallopt(
            libc::M_TRIM_THRESHOLD,
            KEPT_AT_HEAP_TOP_BYTES as libc::c_int,
        );
    }
}

/// Gives the memory freed since the last call back to the system (glibc:
/// `malloc_trim`; elsewhere nothing). Describing a photo allocates and
/// frees hundreds of MiB of tensors between the described photos kept in
/// the heap; without this, the holes they leave are kept and the server's
/// memory grows far past its cache bound.
pub fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free pages of the heap to the system.
    unsafe {
        libc::malloc_trim(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use matseg_query::descriptor::DescriptorMap;

    /// A photo of `w x h` described on a grid of 2 x 2 cells of 3 values.
    fn described(w: u32, h: u32, size: (u32, u32)) -> Arc<Described> {
        let grid = DescriptorMap {
            width: 2,
            height: 2,
            dim: 3,
            data: (0..12).map(|i| (i % 3) as f32).collect(),
        };
        let map = CoarseDescriptors {
            grid,
            width: w as usize,
            height: h as usize,
        };
        let photo = RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, 0]));
        Arc::new(Described::new(photo, map, size))
    }

    #[test]
    fn photos_over_the_cap_are_described_at_it_in_proportion() {
        assert_eq!(described_size(600, 400), (600, 400));
        assert_eq!(described_size(2048, 2048), (2048, 2048));
        for (w, h) in [(6000, 6000), (7300, 5440), (40_000, 1000), (1, 50_000_000)] {
            let (dw, dh) = described_size(w, h);
            let pixels = dw as u64 * dh as u64;
            assert!(pixels <= MAX_DESCRIBED_PIXELS, "{w}x{h}: {dw}x{dh}");
            assert!(
                pixels > MAX_DESCRIBED_PIXELS * 99 / 100 || dw == 1,
                "{w}x{h}: {dw}x{dh}"
            );
            let (own, shrunk) = (w as f64 / h as f64, dw as f64 / dh as f64);
            assert!(
                (own / shrunk - 1.0).abs() < 0.01 || dw == 1,
                "{w}x{h}: {dw}x{dh}"
            );
        }
    }

    #[test]
    fn clicks_and_answers_stay_in_the_photos_own_pixels() {
        let same = described(4, 2, (4, 2));
        assert!(!same.shrunk());
        assert_eq!(same.point(3.5, 1.25), (3.5, 1.25));
        assert_eq!(same.radius(5.0), 5.0);
        let values: Vec<u8> = (0..8).collect();
        assert_eq!(same.at_photo_size(values.clone(), 1), values);
        // Described at half the size each way.
        let half = described(4, 2, (8, 4));
        assert!(half.shrunk());
        assert_eq!(half.point(7.9, 3.9), (3.95, 1.95));
        assert_eq!(half.point(0.0, 0.0), (0.0, 0.0));
        assert_eq!(half.radius(6.0), 3.0);
        let grey = half.at_photo_size(values, 1);
        assert_eq!(grey.len(), 32);
        assert_eq!(&grey[..8], &[0, 0, 1, 1, 2, 2, 3, 3]);
        assert_eq!(&grey[8..16], &grey[..8]);
        assert_eq!(&grey[24..], &[4, 4, 5, 5, 6, 6, 7, 7]);
        let rgb: Vec<u8> = (0..24).collect();
        let rgb = half.at_photo_size(rgb, 3);
        assert_eq!(rgb.len(), 96);
        assert_eq!(&rgb[..9], &[0, 1, 2, 0, 1, 2, 3, 4, 5]);
    }

    #[tokio::test]
    async fn photo_work_takes_turns_and_too_many_waiting_are_refused() {
        let work = Arc::new(PhotoWork::default());
        let first = work.turn("a.jpg").await.unwrap();
        let mut waiting = Vec::new();
        for _ in 0..PHOTO_WORK_WAITING {
            let work = work.clone();
            waiting.push(tokio::spawn(
                async move { work.turn("b.jpg").await.map(drop) },
            ));
        }
        while work.waiting() < PHOTO_WORK_WAITING {
            tokio::task::yield_now().await;
        }
        let refused = work.turn("c.jpg").await.err().unwrap();
        assert_eq!(refused.status(), StatusCode::SERVICE_UNAVAILABLE);
        assert!(
            refused
                .message()
                .starts_with("c.jpg: 16 photos are waiting"),
            "{}",
            refused.message()
        );
        assert_eq!(work.waiting(), PHOTO_WORK_WAITING);
        // A request dropped while it waits is no longer counted.
        waiting.pop().unwrap().abort();
        while work.waiting() == PHOTO_WORK_WAITING {
            tokio::task::yield_now().await;
        }
        drop(first);
        for turn in waiting {
            turn.await.unwrap().unwrap();
        }
        assert_eq!(work.waiting(), 0);
    }

    #[test]
    fn a_description_is_counted_before_it_is_made() {
        let one = described(10, 10, (10, 10));
        let bytes = one.bytes();
        let budget = MemoryBudget::new(2 * bytes + bytes / 2);
        let cache = DescribedCache::new(budget.clone());
        cache.reserve(bytes).keep("a".into(), one.clone());
        cache.reserve(bytes).keep("b".into(), one.clone());
        assert_eq!((cache.len(), budget.held()), (2, 2 * bytes));
        assert!(cache.get("a").is_some());
        // A third under way: the least recently used (b) goes first.
        let third = cache.reserve(bytes);
        assert_eq!(budget.held(), 2 * bytes);
        assert!(cache.get("b").is_none() && cache.get("a").is_some());
        third.keep("c".into(), one.clone());
        assert_eq!(
            (cache.len(), cache.bytes(), budget.held()),
            (2, 2 * bytes, 2 * bytes)
        );
        // One that fails gives its room back.
        drop(cache.reserve(bytes));
        assert_eq!(budget.held(), cache.bytes());
        // One larger than the whole budget: every other goes, it stays.
        let big = cache.reserve(3 * bytes);
        assert!(cache.is_empty());
        assert_eq!(budget.held(), 3 * bytes);
        big.keep("a".into(), one.clone());
        assert_eq!((cache.len(), budget.held()), (1, bytes));
        drop(cache);
        assert_eq!(budget.held(), 0);
    }
}
