//! What the demo's HTML pages share: the style sheet and the cards that
//! show a dataset's samples beside their annotations.

use crate::error::PipelineError;
use crate::files::{create_folder, write_file};
use matseg_data::Dataset;
use matseg_image::io::encode_png_rgb;
use matseg_scene::colourise;
use std::fmt::Write as _;
use std::path::Path;

/// The report pages' shared style sheet.
pub const STYLE: &str = r#"<style>
body { font-family: sans-serif; margin: 1.5em; background: #fafafa; }
.grid { display: grid; grid-template-columns: repeat(auto-fill, minmax(420px, 1fr)); gap: 1em; }
figure { margin: 0; background: #fff; padding: .5em; border: 1px solid #ddd; }
.pair { display: grid; grid-template-columns: 1fr 1fr; gap: 4px; }
.pair img { width: 100%; height: 200px; object-fit: contain; background: #000; }
figcaption { font-size: .8em; color: #444; margin-top: .3em; }
</style>"#;

/// One figure per sample of `dataset` (stored under `out/sub`): the image
/// beside its colour annotation (written to
/// `out/previews/{preview_prefix}KEY_annotation.png`), captioned with size,
/// material count, `describe(sidecar)` and licences.
pub fn sample_cards(
    dataset: &Dataset,
    out: &Path,
    sub: &str,
    preview_prefix: &str,
    describe: impl Fn(&serde_json::Value) -> String,
) -> Result<String, PipelineError> {
    let previews = out.join("previews");
    create_folder(&previews)?;
    let mut cards = String::new();
    for sample in dataset.iter() {
        let sample = sample?;
        let (w, h) = sample.image.dimensions();
        let masks: Vec<Vec<f32>> = sample
            .masks
            .iter()
            .map(|m| m.as_raw().iter().map(|&v| v as f32 / 255.0).collect())
            .collect();
        let slices: Vec<&[f32]> = masks.iter().map(Vec::as_slice).collect();
        let name = format!("{preview_prefix}{}_annotation.png", sample.key);
        let path = previews.join(&name);
        write_file(
            &path,
            &encode_png_rgb(&colourise(w as usize, h as usize, &slices)),
        )?;
        let meta = sample.meta.clone().unwrap_or_default();
        let licences = meta["licences"]
            .as_array()
            .map(|l| {
                l.iter()
                    .filter_map(|v| v.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_default();
        let _ = write!(
            cards,
            r#"<figure><div class="pair"><img src="{sub}/{key}/RGB__RGB.jpg"><img src="previews/{name}"></div>
<figcaption>#{key}: {w}x{h}, {k} material(s), {what}; {licences}</figcaption></figure>
"#,
            key = sample.key,
            k = sample.masks.len(),
            what = describe(&meta),
        );
    }
    Ok(cards)
}
