//! HDR environment maps in the corpus: their radiance statistics, and the
//! conversion of DWAA/DWAB-compressed EXRs (which the Rust `exr` crate cannot
//! decode) into ZIP EXRs through PyPI's OpenEXR in a venv of the cache's
//! own. The conversion keeps every value (no tone mapping, no resizing) and
//! is checked by reading the result back: its largest and mean luminance
//! must match the source's.

use matseg_render::hdr_io::{read_hdr, HdrImage};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The converter script (shared with `scripts/convert-hdris.sh`).
const SCRIPT: &str = include_str!("../../../scripts/convert-hdris.py");

/// The OpenEXR wheel the helper venv installs.
pub const OPENEXR_REQUIREMENT: &str = "OpenEXR==3.5.3";

/// Size and luminance of an environment map (Rec. 709 luminance; the mean
/// weighted by each row's solid angle).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct HdriStats {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Largest luminance.
    pub max_luminance: f64,
    /// Solid-angle-weighted mean luminance.
    pub mean_luminance: f64,
}

impl HdriStats {
    /// The statistics of `img`.
    pub fn of(img: &HdrImage) -> Self {
        let (mut max, mut sum, mut weights) = (0f64, 0f64, 0f64);
        for y in 0..img.height {
            let w = (std::f64::consts::PI * (y as f64 + 0.5) / img.height as f64).sin();
            for p in &img.pixels[y * img.width..(y + 1) * img.width] {
                let lum = 0.2126 * p.x as f64 + 0.7152 * p.y as f64 + 0.0722 * p.z as f64;
                max = max.max(lum);
                sum += lum * w;
                weights += w;
            }
        }
        Self {
            width: img.width,
            height: img.height,
            max_luminance: max,
            mean_luminance: sum / weights.max(f64::MIN_POSITIVE),
        }
    }

    /// Reads `path` and measures it.
    pub fn read(path: &Path) -> Result<Self, String> {
        read_hdr(path)
            .map(|img| Self::of(&img))
            .map_err(|e| e.to_string())
    }

    /// Whether `converted` keeps this source's size and dynamic range: equal
    /// sizes, largest and mean luminance within 1% (half floats round).
    pub fn check_kept_by(&self, converted: &HdriStats) -> Result<(), String> {
        let close = |a: f64, b: f64| (a - b).abs() <= 0.01 * a.abs().max(b.abs()) + 1e-6;
        if (self.width, self.height) != (converted.width, converted.height)
            || !close(self.max_luminance, converted.max_luminance)
            || !close(self.mean_luminance, converted.mean_luminance)
        {
            return Err(format!(
                "conversion changed the map: source {}x{} max {:.4} mean {:.4}, converted {}x{} max {:.4} mean {:.4}",
                self.width, self.height, self.max_luminance, self.mean_luminance,
                converted.width, converted.height, converted.max_luminance, converted.mean_luminance
            ));
        }
        Ok(())
    }
}

/// One line the converter script prints per file.
#[derive(Deserialize)]
struct ScriptLine {
    file: String,
    width: usize,
    height: usize,
    max_luminance: f64,
    mean_luminance: f64,
}

/// The OpenEXR helper: a Python venv under the cache's `tools/` folder.
pub struct OpenExrHelper {
    dir: PathBuf,
}

impl OpenExrHelper {
    /// The helper living in `tools_dir` (made on first use).
    pub fn new(tools_dir: &Path) -> Self {
        Self {
            dir: tools_dir.join("openexr-venv"),
        }
    }

    /// The venv's Python, creating the venv and installing OpenEXR first
    /// when missing.
    fn python(&self) -> Result<PathBuf, String> {
        let python = self.dir.join("bin/python");
        let ready = self.dir.join("ready");
        if ready.is_file() && python.is_file() {
            return Ok(python);
        }
        let run = |cmd: &mut Command, what: &str| -> Result<(), String> {
            let out = cmd
                .output()
                .map_err(|e| format!("{what}: cannot run: {e}"))?;
            if out.status.success() {
                Ok(())
            } else {
                let err = String::from_utf8_lossy(&out.stderr);
                Err(format!(
                    "{what} failed: {}",
                    err.lines().last().unwrap_or("no message")
                ))
            }
        };
        run(
            Command::new("python3").args(["-m", "venv"]).arg(&self.dir),
            "python3 -m venv (the DWAB converter needs Python 3)",
        )?;
        run(
            Command::new(self.dir.join("bin/pip")).args([
                "install",
                "--quiet",
                OPENEXR_REQUIREMENT,
                "numpy",
            ]),
            &format!("pip install {OPENEXR_REQUIREMENT} numpy"),
        )?;
        std::fs::write(&ready, OPENEXR_REQUIREMENT).map_err(|e| e.to_string())?;
        Ok(python)
    }

    /// Converts `inputs` into ZIP EXRs of the same names in `out_dir`;
    /// returns each converted file's path with the source's statistics as
    /// the script measured them. Files the script skipped are missing.
    pub fn convert(
        &self,
        inputs: &[PathBuf],
        out_dir: &Path,
    ) -> Result<Vec<(PathBuf, HdriStats)>, String> {
        let python = self.python()?;
        let script = self.dir.join("convert-hdris.py");
        std::fs::write(&script, SCRIPT).map_err(|e| format!("{}: {e}", script.display()))?;
        let out = Command::new(python)
            .arg(&script)
            .arg(out_dir)
            .args(inputs)
            .output()
            .map_err(|e| format!("OpenEXR helper: cannot run: {e}"))?;
        if !out.status.success() {
            let err = String::from_utf8_lossy(&out.stderr);
            return Err(format!(
                "OpenEXR helper failed: {}",
                err.lines().last().unwrap_or("no message")
            ));
        }
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter(|l| !l.trim().is_empty())
            .map(|l| {
                let line: ScriptLine = serde_json::from_str(l)
                    .map_err(|e| format!("OpenEXR helper printed {l:?}: {e}"))?;
                let stats = HdriStats {
                    width: line.width,
                    height: line.height,
                    max_luminance: line.max_luminance,
                    mean_luminance: line.mean_luminance,
                };
                Ok((out_dir.join(line.file), stats))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use matseg_render::Vec3;

    #[test]
    fn stats_weight_rows_by_solid_angle() {
        // Two rows: the weights are equal (sin(pi/4) = sin(3pi/4)).
        let img = HdrImage {
            width: 2,
            height: 2,
            pixels: vec![
                Vec3::new(1.0, 1.0, 1.0),
                Vec3::new(3.0, 3.0, 3.0),
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 0.0),
            ],
        };
        let s = HdriStats::of(&img);
        assert!((s.max_luminance - 3.0).abs() < 1e-6);
        assert!((s.mean_luminance - 1.0).abs() < 1e-6);
        let mut brighter = s;
        brighter.max_luminance *= 1.1;
        assert!(s.check_kept_by(&s).is_ok());
        assert!(s
            .check_kept_by(&brighter)
            .unwrap_err()
            .contains("changed the map"));
    }
}
