//! Pieces shared by the commands: sources, recipes, progress bars, warnings.

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use matseg_image::LicenceFilter;
use matseg_pipeline::error::PipelineError;
use matseg_pipeline::progress::Progress;
use matseg_pipeline::scenes::SceneSources;
use matseg_pipeline::sources::{Defaults, Libraries};
use matseg_scene::Recipe2d;
use std::path::{Path, PathBuf};

/// Scene kinds, as command-line values (`generate --kind`, `recipe --kind`).
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum SceneKind {
    /// Textures mixed by soft maps over a photo background (pipeline.md §2).
    #[value(name = "2d")]
    TwoD,
    /// Objects carrying several PBR materials split by photo channels, lit
    /// by HDRIs and path traced (pipeline.md §3).
    #[value(name = "3d")]
    ThreeD,
}

/// The `--licences` option of the commands that draw from source folders.
#[derive(clap::Args)]
pub struct LicenceArgs {
    /// Use only sources under these licence families (comma-separated:
    /// cc0, public-domain, mit, bsd, apache, cc-by, cc-by-sa, lgpl, gpl, unknown).
    #[arg(long)]
    licences: Option<String>,
}

impl LicenceArgs {
    /// The filter (every licence when the option is absent).
    pub fn filter(&self) -> Result<LicenceFilter> {
        Ok(LicenceFilter::parse(
            self.licences.as_deref().unwrap_or_default(),
        )?)
    }
}

/// The source folders of the commands that make 2D scenes (`train
/// --online`, `features`, `bench-set make`), with their licence filter.
#[derive(clap::Args)]
pub struct LibraryArgs {
    /// Folders of natural photos the scenes are made from; default: the
    /// fetched corpus, else the bundled assets.
    #[arg(long, num_args = 1..)]
    sources: Vec<PathBuf>,
    /// Folders of textures the scenes are made from; default: the fetched
    /// corpus, else the bundled assets.
    #[arg(long, num_args = 1..)]
    textures: Vec<PathBuf>,
    #[command(flatten)]
    licences: LicenceArgs,
}

impl LibraryArgs {
    /// The libraries of these folders (or the defaults), decoded within
    /// `cache_mb` MiB, with a warning for each unreadable file.
    pub fn load(&self, cache_mb: usize) -> Result<Libraries> {
        load_libraries(
            &self.sources,
            &self.textures,
            cache_mb,
            Defaults::CorpusOrBundled,
            &self.licences.filter()?,
        )
    }
}

/// Scans the photo and texture libraries ([`Libraries::load`]) and prints
/// a warning for each unreadable file.
pub fn load_libraries(
    photos: &[PathBuf],
    textures: &[PathBuf],
    cache_mb: usize,
    defaults: Defaults,
    licences: &LicenceFilter,
) -> Result<Libraries> {
    let libraries = Libraries::load(photos, textures, cache_mb, defaults, licences)?;
    for s in libraries.skipped_at_scan() {
        eprintln!("warning: skipped {}: {}", s.path.display(), s.reason);
    }
    Ok(libraries)
}

/// Prints the source files that failed to decode during the run and the
/// count of all unreadable ones.
pub fn report_skipped(sources: &SceneSources) {
    let late = sources.failed_since_load();
    for s in &late {
        eprintln!("warning: skipped {s}");
    }
    let total = sources.skipped_at_load() + late.len();
    if total > 0 {
        eprintln!("warning: {total} unreadable source file(s) skipped");
    }
}

/// The recipe from `--config` (defaults otherwise), with an optional size range.
pub fn load_recipe(config: Option<&Path>, size_range: Option<&str>) -> Result<Recipe2d> {
    let mut recipe = match config {
        Some(path) => Recipe2d::from_toml_file(path)?,
        None => Recipe2d::default(),
    };
    if let Some(range) = size_range {
        let (lo, hi) = parse_range(range).with_context(|| format!("--size-range {range}"))?;
        recipe.scene.size_min = lo;
        recipe.scene.size_max = hi;
        recipe.validate(&format!("--size-range {range}"))?;
    }
    Ok(recipe)
}

/// Parses `LO..HI` (inclusive) or a single `N`.
pub fn parse_range(text: &str) -> Result<(usize, usize)> {
    let parse = |s: &str| {
        s.trim()
            .parse::<usize>()
            .with_context(|| format!("'{s}' is not a whole number"))
    };
    match text.split_once("..") {
        Some((lo, hi)) => {
            let hi = hi.strip_prefix('=').unwrap_or(hi);
            let (lo, hi) = (parse(lo)?, parse(hi)?);
            if lo > hi {
                bail!("empty range: {lo} > {hi}");
            }
            Ok((lo, hi))
        }
        None => {
            let n = parse(text)?;
            Ok((n, n))
        }
    }
}

/// A progress bar with rate and ETA on stderr (hidden when not a terminal).
fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{elapsed_precise}} [{{bar:40}}] {{pos}}/{{len}} {what} ({{per_sec}}, ETA {{eta}}) {{msg}}"
        ))
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar
}

/// Jobs' progress as a bar on stderr, one per job, made when the job says
/// how long it is, with the job's status as its message; their warnings as
/// `warning: skipped ...` lines.
#[derive(Default)]
pub struct BarProgress {
    bar: std::sync::Mutex<Option<ProgressBar>>,
}

impl BarProgress {
    fn bar(&self) -> std::sync::MutexGuard<'_, Option<ProgressBar>> {
        matseg_image::sync::lock(&self.bar)
    }
}

impl Progress for BarProgress {
    fn start(&self, total: u64, what: &str) {
        *self.bar() = Some(progress_bar(total, what));
    }

    fn advance(&self) {
        self.advance_by(1);
    }

    fn advance_by(&self, steps: u64) {
        if let Some(bar) = self.bar().as_ref() {
            bar.inc(steps);
        }
    }

    fn status(&self, message: &str) {
        if let Some(bar) = self.bar().as_ref() {
            bar.set_message(message.to_string());
        }
    }

    fn finish(&self) {
        if let Some(bar) = self.bar().take() {
            bar.finish_and_clear();
        }
    }

    fn warn(&self, message: &str) {
        eprintln!("warning: skipped {message}");
    }
}

/// An error as one line; a library setting at fault is named by its flag
/// (`mix fraction` as `--mix-fraction`).
pub fn one_line(e: &anyhow::Error) -> String {
    let text = match e.downcast_ref::<PipelineError>() {
        Some(PipelineError::Setting {
            name,
            value,
            message,
        }) => {
            let value = value.as_ref().map(|v| format!(" {v}")).unwrap_or_default();
            format!("--{}{value}: {message}", name.replace(' ', "-"))
        }
        _ => format!("{e:#}"),
    };
    text.replace('\n', " ")
}

/// Reports a command line clap refused: help and the version as clap
/// prints them; an error as one line, `error: WHAT[; tip: HOW] (see
/// matseg ... --help)`, like every other error of the command, exit
/// status 2.
pub fn argument_error(e: clap::Error) -> std::process::ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        let _ = e.print();
        return std::process::ExitCode::from(e.exit_code() as u8);
    }
    eprintln!("{}", argument_error_line(&e.render().to_string()));
    std::process::ExitCode::from(2)
}

/// clap's rendered error as one line: its first line, its tips, and where
/// to look (the usage's command with `--help`).
fn argument_error_line(rendered: &str) -> String {
    let mut line = String::new();
    let mut command = "matseg".to_string();
    for text in rendered.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if line.is_empty() {
            line = text.to_string();
        } else if let Some(tip) = text.strip_prefix("tip:") {
            line = format!("{line}; tip:{tip}");
        } else if let Some(usage) = text.strip_prefix("Usage: ") {
            command = usage
                .split_whitespace()
                .take_while(|w| !w.starts_with('[') && !w.starts_with('<') && !w.starts_with('-'))
                .collect::<Vec<_>>()
                .join(" ");
        }
    }
    format!("{line} (see {command} --help)")
}

/// Sets the global rayon thread count when given.
pub fn init_threads(threads: Option<usize>) -> Result<()> {
    if let Some(t) = threads {
        if t == 0 {
            bail!("--threads must be at least 1");
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_and_reject_nonsense() {
        assert_eq!(parse_range("400..999").unwrap(), (400, 999));
        assert_eq!(parse_range("400..=999").unwrap(), (400, 999));
        assert_eq!(parse_range("512").unwrap(), (512, 512));
        assert!(parse_range("999..400").is_err());
        assert!(parse_range("a..b").is_err());
    }

    #[test]
    fn library_settings_are_named_by_their_flags() {
        let setting = PipelineError::setting("mix fraction", Some(1.5), "expected 0..1");
        assert_eq!(
            one_line(&anyhow::Error::from(setting)),
            "--mix-fraction 1.5: expected 0..1"
        );
        let file = PipelineError::file("a.json", "cannot read");
        assert_eq!(one_line(&anyhow::Error::from(file)), "a.json: cannot read");
    }

    #[test]
    fn clap_errors_become_one_line() {
        let rendered = "error: unexpected argument '--ot' found\n\n  tip: a similar argument exists: '--out'\n\nUsage: matseg track --point <POINTS> --out <OUT> <VIDEO>\n\nFor more information, try '--help'.\n";
        assert_eq!(
            argument_error_line(rendered),
            "error: unexpected argument '--ot' found; tip: a similar argument exists: '--out' (see matseg track --help)"
        );
        let plain = "error: invalid value 'x' for '--radius <RADIUS>': x: expected a number of pixels\n\nFor more information, try '--help'.\n";
        assert_eq!(
            argument_error_line(plain),
            "error: invalid value 'x' for '--radius <RADIUS>': x: expected a number of pixels (see matseg --help)"
        );
    }
}
