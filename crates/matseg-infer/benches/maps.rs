//! `cargo bench -p matseg-infer --bench maps -- FOLDER...`: the shipped
//! model's descriptors of every photo under each folder on both engines,
//! libtorch (matseg-net) and pure Rust (this crate), compared cell by cell
//! on the grid `segment`, `eval` and a click describe a photo on (the four
//! sizes merged): per folder, the photos, the cells, and 1 - cosine at
//! the worst cell and on average. Photos are the `.jpg`, `.jpeg` and `.png` files whose names
//! have one dot (a mask benchmark's `NAME.mask0.png` and `NAME.roi.png` are
//! left out). Cargo runs it in crates/matseg-infer: give absolute paths.
//! scripts/bench-engines.py runs it on every benchmark.

#[path = "../tests/common/mod.rs"]
mod common;

use matseg_image::device::ComputeDevice;
use matseg_infer::InferNet;
use matseg_net::infer::NetModel;
use matseg_query::net::DescriptorNet;
use std::path::{Path, PathBuf};

/// The photos under `dir`, sorted.
fn photos(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    let mut folders = vec![dir.to_path_buf()];
    while let Some(folder) = folders.pop() {
        let listing = std::fs::read_dir(&folder)
            .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", folder.display())))?;
        for entry in listing {
            let path = entry?.path();
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            let photo = [".jpg", ".jpeg", ".png"].iter().any(|e| name.ends_with(e))
                && name.matches('.').count() == 1;
            if path.is_dir() {
                folders.push(path);
            } else if photo {
                found.push(path);
            }
        }
    }
    found.sort();
    Ok(found)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let folders: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let default = Path::new(matseg_model::DEFAULT_MODEL);
    let torch = NetModel::load(default, ComputeDevice::Cpu)?;
    let rust = InferNet::load(default)?;
    println!("| photos | count | cells | 1 - cosine, worst cell | 1 - cosine, mean |");
    println!("|---|---|---|---|---|");
    for folder in &folders {
        let (mut cells, mut sum, mut worst) = (0usize, 0f64, f64::INFINITY);
        let found = photos(Path::new(folder))?;
        for path in &found {
            let photo = matseg_image::io::read_rgb(path)?;
            let (a, b) = (torch.describe_coarse(&photo), rust.describe_coarse(&photo));
            for (x, y) in a
                .grid
                .data
                .chunks(a.grid.dim)
                .zip(b.grid.data.chunks(b.grid.dim))
            {
                let similarity = common::cosine(x, y);
                worst = worst.min(similarity);
                sum += similarity;
                cells += 1;
            }
        }
        let mean = sum / cells.max(1) as f64;
        println!(
            "| {folder} | {} | {cells} | {:.1e} | {:.1e} |",
            found.len(),
            1.0 - worst,
            1.0 - mean,
        );
    }
    Ok(())
}
