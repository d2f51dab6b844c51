//! Benchmark harnesses: what `matseg bench`, `bench-render` and
//! `bench-net` measure and the crate's `cargo bench` targets run, as
//! library calls that return the figures (and a table's text).

pub mod clock;
pub mod generator;
#[cfg(feature = "net")]
pub mod net;
pub mod render;
