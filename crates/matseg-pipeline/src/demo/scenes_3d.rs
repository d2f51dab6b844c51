//! The demo's 3D page: scenes drawn by the 3D builder from the bundled
//! photos, materials and HDRIs, path traced, and shown beside their exact
//! annotations (`scenes-3d.html`).

use super::page::{sample_cards, STYLE};
use crate::error::PipelineError;
use crate::files::write_file;
use crate::files3d::{recipe_3d, Files3d};
use crate::progress::Progress;
use crate::scenes::SceneFolders;
use crate::sources::Defaults;
use matseg_data::{generate_with, Dataset, Format, GenerateOptions, Generator3d, JobSlice};
use matseg_image::{LicenceFilter, MemoryBudget};
use matseg_render::cache::AssetCache;
use std::path::Path;
use std::sync::Arc;

/// Renders `n` 3D samples of side `size` (seed `seed`) into
/// `out/samples-3d`, their assets counted against the process's `budget`,
/// and writes `out/scenes-3d.html`.
pub fn scenes_page(
    out: &Path,
    (n, size, seed): (u64, u32, u64),
    budget: Arc<MemoryBudget>,
    progress: &dyn Progress,
) -> Result<(), PipelineError> {
    let recipe = recipe_3d(None, Some(size), None)?;
    let cache = AssetCache::sharing(budget);
    let files = Files3d::load(
        &SceneFolders::default(),
        &cache,
        Defaults::Bundled,
        &LicenceFilter::default(),
        progress,
    )?;
    for skipped in &files.skipped {
        progress.warn(skipped);
    }
    let samples = out.join("samples-3d");
    let opts = GenerateOptions {
        out: samples.clone(),
        n,
        seed,
        format: Format::Folders,
        shard_size: 1,
        job: JobSlice::ALL,
    };
    let maker = Generator3d {
        recipe: &recipe,
        sources: files.sources(),
        cache: &cache,
        path: None,
    };
    generate_with(&opts, &maker, progress)?;
    let dataset = Dataset::open(&samples)?;
    let cards = sample_cards(&dataset, out, "samples-3d", "samples-3d_", |meta| {
        let scene = &meta["scene"];
        let count = |key: &str| scene[key].as_array().map_or(0, Vec::len);
        let main = scene["objects"]
            .as_array()
            .map_or(0, |o| o.iter().filter(|o| o["main"] == true).count());
        let hdri = scene["environment"]["hdri"]
            .as_str()
            .and_then(|p| Path::new(p).file_name()?.to_str().map(String::from))
            .unwrap_or_else(|| "uniform sky".into());
        format!(
            "{main} main object(s) of {} objects, {} materials in all, {} photo splits, {hdri}",
            count("objects"),
            count("materials"),
            count("maps"),
        )
    })?;
    let html = format!(
        r#"<!doctype html>
<html><head><meta charset="utf-8"><title>matseg demo: 3D scenes</title>
{style}</head><body>
<h1>matseg demo: 3D scenes</h1>
<p><a href="index.html">Back to the 2D scenes.</a></p>
<p>{n} scenes drawn by the 3D builder (pipeline.md §3, seed {seed}) from the bundled photos, the PBR
materials made from the bundled textures and the bundled CC0 HDRIs, path traced at {size}x{size},
{spp} samples per pixel (<code>matseg generate --kind 3d</code>). Left: the image; right: the exact
annotation of the main object (each material in its colour, mixtures mixed, everything else black).
Each sample's <code>meta.json</code> holds its scene description: <code>matseg render</code> renders it again.</p>
<div class="grid">
{cards}</div></body></html>
"#,
        style = STYLE,
        n = dataset.len(),
        spp = recipe.spp,
    );
    let page = out.join("scenes-3d.html");
    write_file(&page, html.as_bytes())
}
