//! One bound on the decoded assets a process holds. Every cache of decoded
//! files (the photo and texture libraries of the 2D generator, the 3D
//! renderer's asset cache) counts its bytes against the same budget, so a
//! process that draws 2D scenes, renders 3D ones and trains holds at most
//! about `limit` bytes of decoded assets in all, not a budget per cache.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// A byte budget shared by the caches of a process.
#[derive(Debug)]
pub struct MemoryBudget {
    limit: usize,
    held: AtomicUsize,
}

impl MemoryBudget {
    /// A budget of `limit` bytes, none held yet.
    pub fn new(limit: usize) -> Arc<Self> {
        Arc::new(Self {
            limit,
            held: AtomicUsize::new(0),
        })
    }

    /// The bound, in bytes.
    pub fn limit(&self) -> usize {
        self.limit
    }

    /// Bytes the caches hold now.
    pub fn held(&self) -> usize {
        self.held.load(Ordering::Relaxed)
    }

    /// Whether `bytes` more would stay within the bound.
    pub fn fits(&self, bytes: usize) -> bool {
        self.held().saturating_add(bytes) <= self.limit
    }

    /// Whether the caches hold more than the bound.
    pub fn exceeded(&self) -> bool {
        self.held() > self.limit
    }

    /// A cache now holds `bytes` more.
    pub fn add(&self, bytes: usize) {
        self.held.fetch_add(bytes, Ordering::Relaxed);
    }

    /// A cache let go of `bytes`.
    pub fn release(&self, bytes: usize) {
        self.held.fetch_sub(bytes, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holdings_add_up_and_are_released() {
        let budget = MemoryBudget::new(100);
        assert!(budget.fits(100) && !budget.fits(101));
        budget.add(60);
        budget.add(50);
        assert!(budget.exceeded());
        budget.release(50);
        assert_eq!(budget.held(), 60);
        assert!(!budget.exceeded() && !budget.fits(41));
    }
}
