//! `matseg recipe`: the default 2D recipe as TOML, a starting point for `--config`.

use anyhow::Result;
use matseg_scene::Recipe2d;

/// Runs `matseg recipe`: prints the default recipe as TOML.
pub fn run() -> Result<()> {
    print!("{}", toml::to_string_pretty(&Recipe2d::default())?);
    Ok(())
}
