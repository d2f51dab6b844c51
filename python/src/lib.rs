//! `matseg._core`: the native half of the `matseg` Python package. It hands
//! Python plain values (sizes, strings, and arrays as buffers numpy wraps
//! without a copy); `python/matseg` turns them into numpy arrays and gives the classes their Python manners (pickling,
//! argument checks, exceptions named after the problem).

mod batches;
mod buffer;
mod dataset;
mod errors;
mod evaluate;
#[cfg(feature = "torch")]
mod features;
mod generator;
mod model;
mod samples;
mod weights;

use pyo3::prelude::*;

/// The module's classes and functions.
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<buffer::Buffer>()?;
    m.add_class::<generator::PyGenerator>()?;
    m.add_class::<dataset::PyDataset>()?;
    #[cfg(feature = "torch")]
    m.add_class::<features::PyFeatureCache>()?;
    m.add_class::<model::PyModel>()?;
    m.add_class::<model::PyTracker>()?;
    m.add_function(wrap_pyfunction!(batches::default_plan, m)?)?;
    #[cfg(feature = "torch")]
    m.add_function(wrap_pyfunction!(batches::matseg_loss, m)?)?;
    m.add_function(wrap_pyfunction!(model::resolve_model, m)?)?;
    m.add_function(wrap_pyfunction!(model::run_files, m)?)?;
    m.add_function(wrap_pyfunction!(samples::read_rgb, m)?)?;
    #[cfg(feature = "torch")]
    m.add_function(wrap_pyfunction!(model::net_constants, m)?)?;
    m.add_function(wrap_pyfunction!(model::net_preset, m)?)?;
    #[cfg(feature = "torch")]
    m.add_function(wrap_pyfunction!(model::train_defaults, m)?)?;
    #[cfg(feature = "torch")]
    m.add_function(wrap_pyfunction!(model::lr_schedule, m)?)?;
    #[cfg(feature = "torch")]
    m.add_function(wrap_pyfunction!(model::plot_losses, m)?)?;
    m.add_function(wrap_pyfunction!(model::score_points, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(weights::read_safetensors, m)?)?;
    m.add_function(wrap_pyfunction!(weights::write_safetensors, m)?)?;
    m.add("MatsegError", m.py().get_type::<errors::MatsegError>())?;
    // Whether this build has what needs libtorch (the `torch` feature).
    m.add("WITH_TORCH", cfg!(feature = "torch"))?;
    m.add(
        "DEFAULT_CACHE_MB",
        matseg_pipeline::sources::DEFAULT_CACHE_MB,
    )?;
    m.add("DEFAULT_RADIUS", matseg_pipeline::segment::DEFAULT_RADIUS)?;
    m.add("DEFAULT_MAX_SIDE", matseg_eval::evaluate::DEFAULT_MAX_SIDE)?;
    m.add(
        "DEFAULT_TRACK_SIDE",
        matseg_pipeline::track::DEFAULT_TRACK_SIDE,
    )?;
    let tracker = matseg_query::tracking::TrackOptions::default();
    m.add(
        "DEFAULT_TRACKER",
        (
            tracker.memory,
            tracker.samples,
            tracker.confident,
            tracker.prior,
            tracker.temperature,
        ),
    )?;
    Ok(())
}
