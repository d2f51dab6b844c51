//! New PBR materials made by mixing existing ones (pipeline.md §5): equal,
//! max or flexible weights, each mix carrying every source's licence.

use crate::error::PipelineError;
use crate::progress::Progress;
use matseg_data::sample_rng;
use matseg_extract::material_library::{
    find_materials, is_library_entry, is_material_folder, read_material, write_material_folder,
    MaterialError, MaterialMaps,
};
use matseg_extract::pbr_mix::{mix_materials, MixRecipe};
use matseg_image::outputs::{Layout, SharedFolder, Sign};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// What a mixing job did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MixReport {
    /// Mixes written now.
    pub written: usize,
    /// Mixes an earlier run wrote.
    pub already: usize,
    /// Materials mixed from.
    pub materials: usize,
}

/// Writes `count` mixes (mix i from (seed, i)) of the materials under
/// `materials` into `out/mixNNNNN` (a folder `matseg pbr-mix` adds to:
/// matseg_image::outputs::SharedFolder), skipping mixes an earlier run
/// wrote.
pub fn make_mixes(
    materials: &Path,
    out: &Path,
    count: u64,
    seed: u64,
    progress: &dyn Progress,
) -> Result<MixReport, PipelineError> {
    let dirs = find_materials(materials)?;
    if dirs.len() < 2 {
        return Err(PipelineError::file(
            materials.display(),
            format!(
                "mixing needs at least two material folders, found {}",
                dirs.len()
            ),
        ));
    }
    let library: Vec<MaterialMaps> = dirs
        .par_iter()
        .map(|d| read_material(d))
        .collect::<Result<_, _>>()?;
    let owns = |path: &Path| is_library_entry(path, COMMAND);
    let layout = Layout {
        command: COMMAND,
        sign: Sign::Marker,
        owns: &owns,
    };
    let shared = SharedFolder::open(out, &layout, &[materials])?;
    let out = shared.dir();
    let todo: Vec<u64> = (0..count)
        .filter(|&i| !mix_dir(out, i).join("material.json").is_file())
        .collect();
    // Every mix folder this run writes, checked before its first byte.
    let names: Vec<PathBuf> = todo.iter().map(|&i| mix_dir(out, i)).collect();
    shared.claim(names.iter().map(PathBuf::as_path), &is_material_folder)?;
    progress.start(todo.len() as u64, "mixes");
    let recipe = MixRecipe::default();
    todo.par_iter()
        .map(|&i| {
            let result = write_mix(out, i, seed, &library, materials, &recipe);
            progress.advance();
            result
        })
        .collect::<Result<Vec<()>, _>>()?;
    progress.finish();
    Ok(MixReport {
        written: todo.len(),
        already: (count - todo.len() as u64) as usize,
        materials: library.len(),
    })
}

/// The command that mixes materials, in matseg's markers.
const COMMAND: &str = "pbr-mix";

/// The folder of mix `i`.
fn mix_dir(out: &Path, i: u64) -> PathBuf {
    out.join(format!("mix{i:05}"))
}

/// Makes mix `i` and writes its folder (through a partial folder, renamed
/// when complete).
fn write_mix(
    out: &Path,
    i: u64,
    seed: u64,
    library: &[MaterialMaps],
    root: &Path,
    recipe: &MixRecipe,
) -> Result<(), MaterialError> {
    let (mixed, record) = mix_materials(&mut sample_rng(seed, i), library, recipe)?;
    let sources: Vec<String> = record
        .sources
        .iter()
        .map(|&s| {
            let d = &library[s].dir;
            d.strip_prefix(root).unwrap_or(d).display().to_string()
        })
        .collect();
    // The mix carries every source's licence (from its licenses.json).
    let mut licences: Vec<String> = record
        .sources
        .iter()
        .map(|&s| folder_licence(&library[s].dir))
        .collect();
    licences.sort();
    licences.dedup();
    let licence = licences.join(" AND ");
    let json = serde_json::json!({
        "sources": sources,
        "mode": record.mode,
        "weights": record.weights,
        "seed": seed,
    });
    write_material_folder(
        &mix_dir(out, i),
        COMMAND,
        &licence,
        |d| mixed.write_maps(d),
        json,
    )
}

/// The licence a material folder's `licenses.json` gives all its files
/// (`"*"`), or `unknown`.
fn folder_licence(dir: &Path) -> String {
    std::fs::read(dir.join("licenses.json"))
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
        .and_then(|v| v["*"].as_str().map(str::to_string))
        .unwrap_or_else(|| matseg_image::library::UNKNOWN_LICENCE.to_string())
}
