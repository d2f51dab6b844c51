//! `matseg recipe`: a default recipe as TOML, a starting point for `--config`.

use crate::common::SceneKind as Kind;
use anyhow::Result;
use matseg_scene::{Recipe2d, Recipe3d};

/// Arguments of `matseg recipe`.
#[derive(clap::Args)]
pub struct Args {
    /// Which generator's recipe.
    #[arg(long, value_enum, default_value = "2d")]
    kind: Kind,
}

/// Runs `matseg recipe`: prints the default recipe of `--kind` as TOML.
pub fn run(args: Args) -> Result<()> {
    let text = match args.kind {
        Kind::TwoD => toml::to_string_pretty(&Recipe2d::default())?,
        Kind::ThreeD => toml::to_string_pretty(&Recipe3d::default())?,
    };
    print!("{text}");
    Ok(())
}
