//! Turning the files taken from a package into corpus files matseg reads:
//! images checked (textures: size, flatness, not a normal map), GIMP
//! patterns and DDS textures to PNG, base64 EXRs decoded, furniture
//! catalogues split into OBJ models, JavaScript meshes to OBJ, PyTorch
//! checkpoints to safetensors; each with a little information for the
//! catalogue. EXRs of any compression (DWAB included) are kept as they are:
//! matseg's HDR reader reads them.

use crate::error::{content, AssetError};
use crate::manifest::Kind;
use image::RgbImage;
use matseg_image::fingerprint::Fingerprint;
use serde_json::{json, Value};
use std::io::Cursor;

/// A corpus file made from a taken file: its name (relative to the
/// package's corpus folder), its bytes and what the catalogue says of it.
#[derive(Clone, Debug, PartialEq)]
pub struct Converted {
    /// Name below the package's corpus folder, `/`-separated.
    pub name: String,
    /// The file's contents.
    pub bytes: Vec<u8>,
    /// Sizes, counts, statistics.
    pub info: Value,
    /// The name of the file this one belongs to (a model's material
    /// library or texture), `None` for a file of its own.
    pub part_of: Option<String>,
}

impl Converted {
    fn primary(name: String, bytes: Vec<u8>, info: Value) -> Self {
        Self {
            name,
            bytes,
            info,
            part_of: None,
        }
    }
}

/// Converts one taken file of kind `kind`; `name` is its corpus name before
/// conversion. An error says what is wrong with the file.
pub fn convert(kind: Kind, name: &str, bytes: Vec<u8>) -> Result<Vec<Converted>, AssetError> {
    let lower = name.to_ascii_lowercase();
    if kind == Kind::Meshes && lower.ends_with(".sh3f") {
        return furniture_models(name, &bytes);
    }
    if kind == Kind::Weights {
        return checkpoint_to_safetensors(name, &bytes);
    }
    if kind == Kind::Photos && lower.ends_with(".edj") {
        let jpeg = crate::eet::eet_photo(&bytes)?;
        return convert_image(kind, &replace_ext(name, ".edj", ".jpg"), "", jpeg).map(|c| vec![c]);
    }
    if matches!(kind, Kind::Photos | Kind::Textures) {
        return convert_image(kind, name, &lower, bytes).map(|c| vec![c]);
    }
    let (name, bytes) = match one_to_one(kind, &lower) {
        Some((from, to, decode)) => (replace_ext(name, from, to), decode(&bytes)?),
        None => (name.to_string(), bytes),
    };
    Ok(vec![Converted::primary(name, bytes, Value::Null)])
}

/// A photo or texture: formats matseg does not read (GIMP patterns, DDS)
/// decoded once to pixels, checked (textures) and written as PNG; JPEG
/// and PNG files checked and kept as they are.
fn convert_image(
    kind: Kind,
    name: &str,
    lower: &str,
    bytes: Vec<u8>,
) -> Result<Converted, AssetError> {
    let textures = kind == Kind::Textures;
    match image_conversion(lower) {
        Some((from, to, decode)) => {
            let img = decode(&bytes)?;
            let info = if textures {
                texture_info(&img)?
            } else {
                photo_info(&img)?
            };
            Ok(Converted::primary(
                replace_ext(name, from, to),
                png(&img)?,
                info,
            ))
        }
        None => {
            let img = matseg_image::io::decode_rgb(&bytes, std::path::Path::new(name))
                .map_err(|e| content(format!("not a readable image: {}", e.message)))?;
            let info = if textures {
                texture_info(&img)?
            } else {
                photo_info(&img)?
            };
            Ok(Converted::primary(name.to_string(), bytes, info))
        }
    }
}

/// A PyTorch checkpoint (legacy or zip) as a safetensors file of the same
/// stem.
fn checkpoint_to_safetensors(name: &str, bytes: &[u8]) -> Result<Vec<Converted>, AssetError> {
    let tensors =
        matseg_weights::read_checkpoint(bytes, name).map_err(|e| content(e.to_string()))?;
    let parameters: usize = tensors
        .iter()
        .map(|t| t.shape.iter().product::<usize>())
        .sum();
    let file = matseg_weights::write_safetensors(&tensors, &[("source", name)]);
    let out = match name.rsplit_once('.') {
        Some((stem, _)) => format!("{stem}.safetensors"),
        None => format!("{name}.safetensors"),
    };
    let info = json!({ "tensors": tensors.len(), "parameters": parameters });
    Ok(vec![Converted::primary(out, file, info)])
}

/// Turns one file's bytes into another's.
type Decode = fn(&[u8]) -> Result<Vec<u8>, AssetError>;

/// A file-to-file conversion: its extension in, its extension out, how.
type OneToOne = (&'static str, &'static str, Decode);

/// Turns an image file's bytes into pixels.
type DecodeImage = fn(&[u8]) -> Result<RgbImage, AssetError>;

/// The decoder a photo or texture named `lower` (lowercase) needs, if any,
/// with its extension in and the PNG's extension out.
fn image_conversion(lower: &str) -> Option<(&'static str, &'static str, DecodeImage)> {
    let table: [(&str, &str, DecodeImage); 2] = [
        (".pat", ".png", gimp_pattern),
        // `.dds.png`: packages ship some textures as both `x.png` and `x.dds`.
        (".dds", ".dds.png", dds_image),
    ];
    table.into_iter().find(|(from, _, _)| lower.ends_with(from))
}

/// The conversion a file of kind `kind` named `lower` (lowercase) needs,
/// if any, besides images: base64 EXR modules to EXR, JavaScript meshes to
/// OBJ.
fn one_to_one(kind: Kind, lower: &str) -> Option<OneToOne> {
    let table: [(Kind, &str, &str, Decode); 2] = [
        (Kind::Hdris, ".exr.js", ".exr", base64_data_url),
        (Kind::Meshes, ".js", ".obj", js_mesh_to_obj),
    ];
    table
        .into_iter()
        .find(|(k, from, _, _)| *k == kind && lower.ends_with(from))
        .map(|(_, from, to, f)| (from, to, f))
}

fn replace_ext(name: &str, old: &str, new: &str) -> String {
    format!("{}{new}", &name[..name.len() - old.len()])
}

/// The smallest side a photo may have: the 2D generator's scenes are 400
/// to 999 pixels, and a smaller photo would be magnified into blur.
pub const MIN_PHOTO_SIDE: u32 = 200;

/// Width, height and [`Fingerprint`] of a photo, after checking that it
/// is at least [`MIN_PHOTO_SIDE`] pixels a side.
fn photo_info(img: &RgbImage) -> Result<Value, AssetError> {
    let (w, h) = img.dimensions();
    if w.min(h) < MIN_PHOTO_SIDE {
        return Err(content(format!(
            "{w}x{h} is too small for a photo source (at least {MIN_PHOTO_SIDE} pixels a side)"
        )));
    }
    Ok(json!({ "width": w, "height": h, "fingerprint": Fingerprint::of(img).to_hex() }))
}

/// The smallest side a texture may have: smaller ones are icons or
/// placeholders, and would be magnified into blur.
pub const MIN_TEXTURE_SIDE: u32 = 32;

/// Width, height and mean colour of a texture, after checking that it is
/// one: at least [`MIN_TEXTURE_SIDE`] pixels a side, not flat, and not a
/// tangent-space normal map (games ship those beside their colour maps,
/// often without a telling name: bluish, red and green about mid-grey, and
/// blue at least half on nearly every pixel).
fn texture_info(img: &RgbImage) -> Result<Value, AssetError> {
    let (w, h) = img.dimensions();
    if w.min(h) < MIN_TEXTURE_SIDE {
        return Err(content(format!(
            "{w}x{h} is too small for a texture (sides of at least {MIN_TEXTURE_SIDE})"
        )));
    }
    let n = f64::from(w) * f64::from(h);
    let mut sum = [0f64; 3];
    let mut sum_sq = 0f64;
    let mut blue_half = 0u64;
    for p in img.pixels() {
        for (s, &v) in sum.iter_mut().zip(&p.0) {
            *s += f64::from(v);
        }
        let grey = p.0.iter().map(|&v| f64::from(v)).sum::<f64>() / 3.0;
        sum_sq += grey * grey;
        blue_half += u64::from(p.0[2] >= 128);
    }
    let mean = sum.map(|s| s / n);
    let grey_mean = mean.iter().sum::<f64>() / 3.0;
    let grey_sd = (sum_sq / n - grey_mean * grey_mean).max(0.0).sqrt();
    let rounded = mean.map(|m| m.round() as u8);
    if grey_sd < 1.0 {
        return Err(content(format!(
            "flat: one colour {rounded:?} (a placeholder, not a texture)"
        )));
    }
    let near_mid = |m: f64| (m - 128.0).abs() < 32.0;
    if mean[2] >= 180.0 && near_mid(mean[0]) && near_mid(mean[1]) && blue_half as f64 >= 0.99 * n {
        return Err(content(format!(
            "looks like a normal map (mean colour {rounded:?}), not a colour texture"
        )));
    }
    Ok(json!({ "width": w, "height": h, "mean_rgb": rounded }))
}

/// A `.dds` texture's largest mipmap level.
pub fn dds_image(bytes: &[u8]) -> Result<RgbImage, AssetError> {
    let dds = crate::dds::decode_dds(bytes)?;
    Ok(RgbImage::from_raw(dds.width, dds.height, dds.rgb).expect("w * h * 3 bytes"))
}

/// `img` encoded as PNG.
fn png(img: &RgbImage) -> Result<Vec<u8>, AssetError> {
    let mut out = Vec::new();
    img.write_to(&mut Cursor::new(&mut out), image::ImageFormat::Png)
        .map_err(|e| content(format!("PNG: {e}")))?;
    Ok(out)
}

/// A GIMP pattern (`.pat`: a big-endian header, magic `GPAT`, then 1-4
/// bytes per pixel: grey, grey+alpha, RGB, RGBA) as RGB pixels; alpha is
/// dropped, grey repeated.
pub fn gimp_pattern(bytes: &[u8]) -> Result<RgbImage, AssetError> {
    let word = |i: usize| {
        bytes
            .get(4 * i..4 * i + 4)
            .map(|b| u32::from_be_bytes(b.try_into().expect("4 bytes")) as usize)
            .ok_or_else(|| content("GIMP pattern: truncated header"))
    };
    let (header, version, width, height, depth) =
        (word(0)?, word(1)?, word(2)?, word(3)?, word(4)?);
    if bytes.get(20..24) != Some(b"GPAT") || version != 1 {
        return Err(content("not a GIMP pattern (no GPAT magic, version 1)"));
    }
    if !(1..=4).contains(&depth) || width == 0 || height == 0 || header < 24 {
        return Err(content(format!(
            "GIMP pattern: bad header ({width}x{height}, {depth} bytes per pixel)"
        )));
    }
    let pixels = bytes
        .get(header..header + width * height * depth)
        .ok_or_else(|| content("GIMP pattern: truncated pixels"))?;
    let rgb: Vec<u8> = pixels
        .chunks_exact(depth)
        .flat_map(|p| {
            if depth <= 2 {
                [p[0]; 3]
            } else {
                [p[0], p[1], p[2]]
            }
        })
        .collect();
    Ok(RgbImage::from_raw(width as u32, height as u32, rgb).expect("sized"))
}

/// The bytes of the base64 `data:` URL inside a JavaScript module
/// (`export default 'data:application/exr;base64,...'`).
pub fn base64_data_url(js: &[u8]) -> Result<Vec<u8>, AssetError> {
    let text = String::from_utf8_lossy(js);
    let start = text
        .find(";base64,")
        .ok_or_else(|| content("no base64 data URL in the module"))?
        + 8;
    let body = &text[start..];
    let end = body
        .find(['\'', '"', '`'])
        .ok_or_else(|| content("unterminated data URL"))?;
    base64_decode(&body[..end])
}

fn base64_decode(text: &str) -> Result<Vec<u8>, AssetError> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => Some(c - b'A'),
        b'a'..=b'z' => Some(c - b'a' + 26),
        b'0'..=b'9' => Some(c - b'0' + 52),
        b'+' | b'-' => Some(62),
        b'/' | b'_' => Some(63),
        _ => None,
    };
    let mut out = Vec::with_capacity(text.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0);
    for &c in text.trim_end_matches('=').as_bytes() {
        if c.is_ascii_whitespace() {
            continue;
        }
        let v =
            value(c).ok_or_else(|| content(format!("invalid base64 character {:?}", c as char)))?;
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    Ok(out)
}

/// A JavaScript mesh module (`exports.positions=[[x,y,z],...]` and
/// `exports.cells=[[i,j,k],...]`, as the npm `bunny` and `teapot` packages
/// ship them) as OBJ text.
pub fn js_mesh_to_obj(js: &[u8]) -> Result<Vec<u8>, AssetError> {
    let text = String::from_utf8_lossy(js);
    let array_after = |key: &str| -> Result<serde_json::Value, AssetError> {
        let at = text
            .find(&format!("{key}="))
            .or_else(|| text.find(&format!("{key} =")))
            .ok_or_else(|| content(format!("no `{key}` array")))?;
        let rest = &text[at..];
        let start = rest
            .find('[')
            .ok_or_else(|| content(format!("no `{key}` array")))?;
        serde_json::Deserializer::from_str(&rest[start..])
            .into_iter::<Value>()
            .next()
            .ok_or_else(|| content(format!("no `{key}` array")))?
            .map_err(|e| content(format!("`{key}`: {e}")))
    };
    let positions: Vec<[f64; 3]> = serde_json::from_value(array_after("positions")?)
        .map_err(|e| content(format!("`positions`: {e}")))?;
    let cells: Vec<Vec<usize>> = serde_json::from_value(array_after("cells")?)
        .map_err(|e| content(format!("`cells`: {e}")))?;
    let mut obj = String::with_capacity(positions.len() * 40 + cells.len() * 24);
    for [x, y, z] in &positions {
        obj.push_str(&format!("v {x} {y} {z}\n"));
    }
    for cell in &cells {
        if cell.len() < 3 || cell.iter().any(|&i| i >= positions.len()) {
            return Err(content(format!(
                "`cells`: face {cell:?} is not a polygon of the {} positions",
                positions.len()
            )));
        }
        let ids: Vec<String> = cell.iter().map(|i| (i + 1).to_string()).collect();
        obj.push_str(&format!("f {}\n", ids.join(" ")));
    }
    Ok(obj.into_bytes())
}

/// The models of a Sweet Home 3D furniture catalogue (`.sh3f`: a zip with
/// `PluginFurnitureCatalog.properties` naming each `model#N`): every OBJ
/// with the material libraries and textures it references, under
/// `STEM/` + its path in the zip.
pub fn furniture_models(name: &str, bytes: &[u8]) -> Result<Vec<Converted>, AssetError> {
    let stem = name.strip_suffix(".sh3f").unwrap_or(name);
    let zip = matseg_weights::zip::ZipArchive::new(bytes)?;
    let properties = zip.read("PluginFurnitureCatalog.properties")?;
    let models = model_paths(&String::from_utf8_lossy(&properties));
    if models.is_empty() {
        return Err(content(
            "no model#N entries in PluginFurnitureCatalog.properties",
        ));
    }
    let names: std::collections::HashSet<&str> = zip.names().collect();
    let mut out: Vec<Converted> = Vec::new();
    let mut taken = std::collections::HashSet::new();
    for model in models {
        if !model.to_ascii_lowercase().ends_with(".obj") || !names.contains(model.as_str()) {
            continue;
        }
        let obj = zip.read(&model)?;
        let dir = model.rsplit_once('/').map_or("", |(d, _)| d);
        let mut files = Vec::new();
        for mtl in referenced(&obj, &["mtllib"]) {
            let mtl_path = join(dir, &mtl);
            let Ok(mtl_bytes) = zip.read(&mtl_path) else {
                continue;
            };
            for texture in referenced(
                &mtl_bytes,
                &[
                    "map_Kd", "map_Ka", "map_Ks", "map_d", "map_bump", "bump", "map_Bump",
                ],
            ) {
                let tex_path = join(dir, &texture);
                if let Ok(tex) = zip.read(&tex_path) {
                    files.push((tex_path, tex));
                }
            }
            files.push((mtl_path, mtl_bytes));
        }
        let model_name = format!("{stem}/{model}");
        if taken.insert(model.clone()) {
            out.push(Converted::primary(model_name.clone(), obj, Value::Null));
        }
        // A material or texture several models share belongs to the first.
        for (path, data) in files {
            if taken.insert(path.clone()) {
                out.push(Converted {
                    name: format!("{stem}/{path}"),
                    bytes: data,
                    info: Value::Null,
                    part_of: Some(model_name.clone()),
                });
            }
        }
    }
    Ok(out)
}

/// `model#N` values of a Java properties text, without the leading `/`.
fn model_paths(properties: &str) -> Vec<String> {
    properties
        .lines()
        .filter_map(|l| l.trim().split_once('='))
        .filter(|(k, _)| k.trim().starts_with("model#"))
        .map(|(_, v)| v.trim().trim_start_matches('/').to_string())
        .collect()
}

/// The file names the lines starting with one of `keys` reference (the
/// last word of the line: OBJ/MTL options come before the name).
fn referenced(text: &[u8], keys: &[&str]) -> Vec<String> {
    String::from_utf8_lossy(text)
        .lines()
        .filter_map(|l| {
            let mut words = l.split_whitespace();
            let key = words.next()?;
            keys.contains(&key)
                .then(|| words.last().map(String::from))
                .flatten()
        })
        .collect()
}

fn join(dir: &str, name: &str) -> String {
    let name = name.replace('\\', "/");
    if dir.is_empty() {
        name
    } else {
        format!("{dir}/{name}")
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use crate::archive::fixtures::zip;

    #[test]
    fn gimp_pattern_decodes_to_the_same_pixels() {
        let mut pat = Vec::new();
        for v in [28u32, 1, 2, 1, 3] {
            pat.extend(v.to_be_bytes());
        }
        pat.extend(b"GPAT");
        pat.extend(b"ab\0\0");
        pat.extend([10, 20, 30, 40, 50, 60]);
        let img = gimp_pattern(&pat).unwrap();
        assert_eq!(img.dimensions(), (2, 1));
        assert_eq!(img.into_raw(), vec![10, 20, 30, 40, 50, 60]);
        assert!(gimp_pattern(&pat[..30])
            .unwrap_err()
            .to_string()
            .contains("truncated"));
        assert!(gimp_pattern(b"0123456789012345678901234")
            .unwrap_err()
            .to_string()
            .contains("GPAT"));
    }

    fn rgb_image(w: u32, h: u32, pixel: impl Fn(u32, u32) -> [u8; 3]) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| image::Rgb(pixel(x, y)))
    }

    #[test]
    fn textures_are_checked_for_size_flatness_and_normal_maps() {
        let stone = |x: u32, y: u32| [90 + (x * 7 % 50) as u8, 80 + (y * 3 % 40) as u8, 70];
        let info = texture_info(&rgb_image(40, 32, stone)).unwrap();
        assert_eq!(
            (info["width"].as_u64(), info["height"].as_u64()),
            (Some(40), Some(32))
        );
        let e = texture_info(&rgb_image(40, 31, stone))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("40x31 is too small"), "{e}");
        let e = texture_info(&rgb_image(64, 64, |_, _| [200, 10, 10]))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("flat: one colour [200, 10, 10]"), "{e}");
        // A normal map: R and G vary about 128, B high everywhere.
        let normal = |x: u32, y: u32| {
            [
                100 + (x % 56) as u8,
                110 + (y % 40) as u8,
                200 + (x % 50) as u8,
            ]
        };
        let e = texture_info(&rgb_image(64, 64, normal))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("looks like a normal map"), "{e}");
        // A blue texture with dark patches is not one (blue < 128 on them).
        let tiles = |x: u32, y: u32| {
            if (x / 8 + y / 8).is_multiple_of(4) {
                [20, 20, 60]
            } else {
                normal(x, y)
            }
        };
        assert!(texture_info(&rgb_image(64, 64, tiles)).is_ok());
    }

    #[test]
    fn base64_data_urls_decode() {
        let js = b"export default 'data:application/exr;base64,TWF0U2VnIQ=='\n";
        assert_eq!(base64_data_url(js).unwrap(), b"MatSeg!");
        assert!(base64_data_url(b"export default 1")
            .unwrap_err()
            .to_string()
            .contains("no base64"));
    }

    #[test]
    fn js_meshes_become_obj_the_mesh_reader_accepts() {
        let js = b"exports.positions=[[0,0,0],[1,0,0],[0,1,0],[0,0,1]]\nexports.cells=[[0,1,2],[0,1,3],[0,2,3],[1,2,3]]\n";
        let obj = js_mesh_to_obj(js).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.obj");
        std::fs::write(&path, &obj).unwrap();
        let mesh = matseg_render::mesh_io::read_mesh(&path).unwrap();
        assert_eq!((mesh.positions.len(), mesh.triangles.len()), (4, 4));
        let bad = b"exports.positions=[[0,0,0]]\nexports.cells=[[0,1,2]]";
        assert!(js_mesh_to_obj(bad)
            .unwrap_err()
            .to_string()
            .contains("not a polygon"));
    }

    #[test]
    fn furniture_catalogue_gives_each_model_with_its_files() {
        let props = b"id=x\nmodel#1=/set/chair/chair.obj\nmodel#2=/set/missing.obj\n";
        let obj = b"mtllib chair.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let mtl = b"newmtl wood\nmap_Kd -s 1 1 1 wood.png\n";
        let sh3f = zip(&[
            ("PluginFurnitureCatalog.properties", props),
            ("set/chair/chair.obj", obj),
            ("set/chair/chair.mtl", mtl),
            ("set/chair/wood.png", b"png"),
            ("set/chair/unused.png", b"png"),
        ]);
        let out = furniture_models("Set.sh3f", &sh3f).unwrap();
        let names: Vec<(&str, Option<&str>)> = out
            .iter()
            .map(|c| (c.name.as_str(), c.part_of.as_deref()))
            .collect();
        let chair = Some("Set/set/chair/chair.obj");
        assert_eq!(
            names,
            [
                ("Set/set/chair/chair.obj", None),
                ("Set/set/chair/wood.png", chair),
                ("Set/set/chair/chair.mtl", chair)
            ]
        );
        let e = furniture_models(
            "E.sh3f",
            &zip(&[("PluginFurnitureCatalog.properties", b"id=x\n")]),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("no model#N"), "{e}");
    }
}
