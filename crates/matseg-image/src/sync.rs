//! Locks that outlive a panic. The caches, tallies and job tables behind
//! this project's mutexes are whole between statements, so a thread that
//! panicked while holding one (a decoder giving up on a bad file, say) must
//! not stop every later caller: [`lock`] hands out the value all the same.

use std::sync::{Mutex, MutexGuard, PoisonError};

/// The value behind `mutex`, held until the guard is dropped, whether or
/// not an earlier holder panicked.
pub fn lock<T: ?Sized>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_poisoned_mutex_still_hands_out_its_value() {
        let tally = Mutex::new(vec![1]);
        let panicked = std::thread::scope(|s| {
            s.spawn(|| {
                let mut held = lock(&tally);
                held.push(2);
                panic!("a holder gives up");
            })
            .join()
        });
        assert!(panicked.is_err() && tally.is_poisoned());
        lock(&tally).push(3);
        assert_eq!(*lock(&tally), [1, 2, 3]);
    }
}
