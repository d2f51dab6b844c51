//! What the engine comparisons share (tests/equality.rs, benches/maps.rs).

/// The cosine of two descriptors, computed in f64.
pub fn cosine(x: &[f32], y: &[f32]) -> f64 {
    let dot: f64 = x
        .iter()
        .zip(y)
        .map(|(p, q)| f64::from(*p) * f64::from(*q))
        .sum();
    let norm = |v: &[f32]| v.iter().map(|p| f64::from(*p).powi(2)).sum::<f64>().sqrt();
    dot / (norm(x) * norm(y)).max(1e-12)
}
