//! Reading datasets back: MatSeg folders (ours and the original's, including
//! the 3D set's `mask001.png` naming) and WebDataset shards, with random access.

use crate::encode::EncodedSample;
use crate::folders::{FINISHED_FILE, IMAGE_FILE, META_FILE, PARTIAL_SUFFIX, ROI_FILE};
use image::{GrayImage, RgbImage};
use matseg_image::io::{decode_grey, decode_rgb};
use matseg_image::{ImageIoError, Plane};
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// One sample as stored.
#[derive(Clone, Debug)]
pub struct Sample {
    /// Folder name or shard key.
    pub key: String,
    /// The image.
    pub image: RgbImage,
    /// The 8-bit soft masks, in material order.
    pub masks: Vec<GrayImage>,
    /// The ROI mask, when stored.
    pub roi: Option<GrayImage>,
    /// The sidecar, when stored.
    pub meta: Option<serde_json::Value>,
}

/// What training reads from a sample (pipeline.md §7.1): `s = sum of masks`,
/// ROI = `s >= 10`, weight_k = `mask_k / s`.
#[derive(Clone, Debug)]
pub struct TrainingTargets {
    /// Per-material weights, summing to 1 inside the ROI.
    pub weights: Vec<Plane>,
    /// 1 inside the ROI, 0 outside.
    pub roi: Plane,
}

/// Mask sums below this are outside the ROI for training.
pub const ROI_MIN_MASK_SUM: u32 = 10;

impl Sample {
    /// The training interpretation of the masks.
    pub fn targets(&self) -> TrainingTargets {
        let (w, h) = self.image.dimensions();
        let n = (w * h) as usize;
        let mut sums = vec![0u32; n];
        for m in &self.masks {
            for (s, &v) in sums.iter_mut().zip(m.as_raw()) {
                *s += v as u32;
            }
        }
        let weights = self
            .masks
            .iter()
            .map(|m| {
                let data = m
                    .as_raw()
                    .iter()
                    .zip(&sums)
                    .map(|(&v, &s)| if s > 0 { v as f32 / s as f32 } else { 0.0 })
                    .collect();
                Plane::from_vec(w as usize, h as usize, data)
            })
            .collect();
        let roi = sums
            .iter()
            .map(|&s| if s >= ROI_MIN_MASK_SUM { 1.0 } else { 0.0 })
            .collect();
        TrainingTargets {
            weights,
            roi: Plane::from_vec(w as usize, h as usize, roi),
        }
    }
}

/// A dataset that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// File system error.
    #[error("{}: {reason}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// An image member failed to decode.
    #[error(transparent)]
    Image(#[from] ImageIoError),
    /// The layout is wrong.
    #[error("{}: {reason}", path.display())]
    Format {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> ReadError + '_ {
    move |e| ReadError::Io {
        path: path.to_path_buf(),
        reason: one_line(&e.to_string()),
    }
}

/// `message` on one line, its control characters escaped: a tar error
/// quotes the name in a damaged header, which may hold any bytes.
fn one_line(message: &str) -> String {
    message
        .chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

#[derive(Clone, Debug)]
struct Member {
    suffix: String,
    offset: u64,
    size: u64,
}

#[derive(Clone, Debug)]
enum Location {
    Folder(PathBuf),
    Shard {
        path: Arc<PathBuf>,
        key: String,
        members: Vec<Member>,
    },
}

/// An opened dataset: the list of complete samples, read on demand.
#[derive(Clone, Debug)]
pub struct Dataset {
    samples: Vec<Location>,
    incomplete: usize,
}

impl Dataset {
    /// Opens a folder of sample folders and/or `.tar` shards, or one shard.
    /// Sample folders without `Finished.txt` and `.tmp` shards are left out.
    pub fn open(root: &Path) -> Result<Self, ReadError> {
        let mut ds = Dataset {
            samples: Vec::new(),
            incomplete: 0,
        };
        if root.is_file() {
            ds.samples.extend(index_shard(root)?);
            return Ok(ds);
        }
        let listing = std::fs::read_dir(root).map_err(io_err(root))?;
        let mut paths: Vec<PathBuf> = listing.filter_map(|e| e.ok().map(|e| e.path())).collect();
        paths.sort();
        for path in paths {
            if path.is_dir() {
                let partial = path.to_string_lossy().ends_with(PARTIAL_SUFFIX);
                if !partial && path.join(FINISHED_FILE).is_file() {
                    ds.samples.push(Location::Folder(path));
                } else if partial || path.join(IMAGE_FILE).exists() {
                    ds.incomplete += 1;
                }
            } else if path.extension().is_some_and(|e| e == "tar") {
                ds.samples.extend(index_shard(&path)?);
            }
        }
        if ds.samples.is_empty() {
            return Err(ReadError::Format {
                path: root.to_path_buf(),
                reason: "no complete samples (MatSeg folders with Finished.txt, or .tar shards)"
                    .into(),
            });
        }
        Ok(ds)
    }

    /// Number of complete samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Sample folders left out because they are incomplete.
    pub fn incomplete(&self) -> usize {
        self.incomplete
    }

    /// Reads sample `i`.
    pub fn get(&self, i: usize) -> Result<Sample, ReadError> {
        match &self.samples[i] {
            Location::Folder(dir) => read_folder_sample(dir),
            Location::Shard { path, key, members } => read_shard_sample(path, key, members),
        }
    }

    /// The key of sample `i` (its folder's name or its shard key), without
    /// reading it.
    pub fn key(&self, i: usize) -> String {
        match &self.samples[i] {
            Location::Folder(dir) => dir
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            Location::Shard { key, .. } => key.clone(),
        }
    }

    /// Reads every sample in order.
    pub fn iter(&self) -> impl Iterator<Item = Result<Sample, ReadError>> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }
}

/// The mask index in `mask0.png` / `mask001.png`, if the name is a mask.
fn mask_index(name: &str) -> Option<u32> {
    name.strip_prefix("mask")?
        .strip_suffix(".png")?
        .parse()
        .ok()
}

/// The masks a sample's sidecar (our `meta.json`) says it has: a 2D
/// scene's material layers, or a 3D scene's main-object materials; none
/// for a sidecar that does not say (another tool's dataset).
fn listed_masks(meta: &serde_json::Value) -> Option<usize> {
    match meta["kind"].as_str()? {
        "2d" => meta["scene"]["materials"].as_array().map(Vec::len),
        "3d" => {
            serde_json::from_value::<matseg_render::scene::SceneDescription>(meta["scene"].clone())
                .ok()
                .map(|scene| scene.annotated_materials().len())
        }
        _ => None,
    }
}

/// Refuses a sample folder `dir` whose masks (`mask0.png`... by index)
/// are not the `mask0.png` to `maskK.png` its sidecar lists, naming the
/// first missing or extra one: a lost mask must not shift the others'
/// materials.
fn check_listed_masks(
    dir: &Path,
    indices: &[u32],
    meta: Option<&serde_json::Value>,
) -> Result<(), ReadError> {
    let Some(listed) = meta.and_then(listed_masks) else {
        return Ok(());
    };
    let want = 0..listed as u32;
    let missing = want.clone().find(|k| !indices.contains(k));
    let extra = indices.iter().find(|k| !want.contains(k));
    let reason = match (missing, extra) {
        (Some(k), _) => format!(
            "{} is missing: meta.json lists {listed} materials",
            crate::folders::mask_file(k as usize)
        ),
        (None, Some(&k)) => format!(
            "holds {} beyond the {listed} materials meta.json lists",
            crate::folders::mask_file(k as usize)
        ),
        (None, None) => return Ok(()),
    };
    Err(ReadError::Format {
        path: dir.to_path_buf(),
        reason,
    })
}

/// Reads one MatSeg sample folder.
pub fn read_folder_sample(dir: &Path) -> Result<Sample, ReadError> {
    let read = |name: &str| {
        let p = dir.join(name);
        std::fs::read(&p).map_err(|e| ReadError::Io {
            path: p.clone(),
            reason: e.to_string(),
        })
    };
    let image = decode_rgb(&read(IMAGE_FILE)?, &dir.join(IMAGE_FILE))?;
    let mut masks: Vec<(u32, PathBuf)> = std::fs::read_dir(dir)
        .map_err(io_err(dir))?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            mask_index(&name).map(|k| (k, e.path()))
        })
        .collect();
    masks.sort();
    let meta = if dir.join(META_FILE).is_file() {
        let p = dir.join(META_FILE);
        Some(
            serde_json::from_slice(&read(META_FILE)?).map_err(|e| ReadError::Format {
                path: p,
                reason: e.to_string(),
            })?,
        )
    } else {
        None
    };
    let indices: Vec<u32> = masks.iter().map(|(k, _)| *k).collect();
    check_listed_masks(dir, &indices, meta.as_ref())?;
    let masks = masks
        .iter()
        .map(|(_, p)| {
            let bytes = std::fs::read(p).map_err(io_err(p))?;
            let m = decode_grey(&bytes, p)?;
            check_size(p, m.dimensions(), image.dimensions())?;
            Ok(m)
        })
        .collect::<Result<Vec<_>, ReadError>>()?;
    let roi = if dir.join(ROI_FILE).is_file() {
        Some(decode_grey(&read(ROI_FILE)?, &dir.join(ROI_FILE))?)
    } else {
        None
    };
    Ok(Sample {
        key: dir
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned(),
        image,
        masks,
        roi,
        meta,
    })
}

/// Decodes a sample as made by a [`crate::SampleMaker`], before it is
/// written: the same pixels and sidecar a reader gets back from the folder
/// or shard it is written to (key: the folder name, `NNNNNNNN`).
pub fn decode_encoded(sample: &EncodedSample) -> Result<Sample, ReadError> {
    let key = crate::folders::sample_dir(Path::new(""), sample.index)
        .display()
        .to_string();
    let name = |file: &str| PathBuf::from(format!("{key}/{file}"));
    let image = decode_rgb(&sample.jpg, &name(IMAGE_FILE))?;
    let masks = sample
        .masks
        .iter()
        .enumerate()
        .map(|(k, bytes)| decode_grey(bytes, &name(&crate::folders::mask_file(k))))
        .collect::<Result<Vec<_>, _>>()?;
    let roi = decode_grey(&sample.roi, &name(ROI_FILE))?;
    let meta = serde_json::from_slice(&sample.json).map_err(|e| ReadError::Format {
        path: name(META_FILE),
        reason: e.to_string(),
    })?;
    Ok(Sample {
        key,
        image,
        masks,
        roi: Some(roi),
        meta: Some(meta),
    })
}

fn check_size(path: &Path, got: (u32, u32), want: (u32, u32)) -> Result<(), ReadError> {
    if got != want {
        return Err(ReadError::Format {
            path: path.to_path_buf(),
            reason: format!("is {}x{}, the image is {}x{}", got.0, got.1, want.0, want.1),
        });
    }
    Ok(())
}

/// A file inside a tar archive: its name, and where its bytes are.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TarMember {
    /// Its path in the archive.
    pub name: String,
    /// Offset of its first byte in the archive file.
    pub offset: u64,
    /// Its size in bytes.
    pub size: u64,
}

/// The members of the tar archive `path`, in archive order. A truncated
/// archive (a member's data past the end of the file) is an error.
pub fn index_tar(path: &Path) -> Result<Vec<TarMember>, ReadError> {
    let file = std::fs::File::open(path).map_err(io_err(path))?;
    let length = file.metadata().map_err(io_err(path))?.len();
    let mut archive = tar::Archive::new(file);
    let mut members = Vec::new();
    for entry in archive.entries().map_err(io_err(path))? {
        let entry = entry.map_err(io_err(path))?;
        let name = entry
            .path()
            .map_err(io_err(path))?
            .to_string_lossy()
            .into_owned();
        let (offset, size) = (entry.raw_file_position(), entry.size());
        if offset + size > length {
            return Err(ReadError::Format {
                path: path.to_path_buf(),
                reason: format!("truncated: {name} ends past the end of the file"),
            });
        }
        members.push(TarMember { name, offset, size });
    }
    Ok(members)
}

/// The bytes of `member` of the tar archive `path`.
pub fn read_tar_member(path: &Path, member: &TarMember) -> Result<Vec<u8>, ReadError> {
    let mut file = std::fs::File::open(path).map_err(io_err(path))?;
    let mut bytes = vec![0u8; member.size as usize];
    file.seek(SeekFrom::Start(member.offset))
        .map_err(io_err(path))?;
    file.read_exact(&mut bytes).map_err(io_err(path))?;
    Ok(bytes)
}

fn index_shard(path: &Path) -> Result<Vec<Location>, ReadError> {
    let shared = Arc::new(path.to_path_buf());
    let mut out: Vec<Location> = Vec::new();
    for TarMember { name, offset, size } in index_tar(path)? {
        let Some((key, suffix)) = name.split_once('.') else {
            continue;
        };
        let member = Member {
            suffix: suffix.to_string(),
            offset,
            size,
        };
        match out.last_mut() {
            Some(Location::Shard {
                key: k, members, ..
            }) if k == key => members.push(member),
            _ => out.push(Location::Shard {
                path: shared.clone(),
                key: key.to_string(),
                members: vec![member],
            }),
        }
    }
    Ok(out)
}

fn read_shard_sample(path: &Path, key: &str, members: &[Member]) -> Result<Sample, ReadError> {
    let mut file = std::fs::File::open(path).map_err(io_err(path))?;
    let mut image = None;
    let mut masks: Vec<(u32, GrayImage)> = Vec::new();
    let mut roi = None;
    let mut meta = None;
    for m in members {
        let mut bytes = vec![0u8; m.size as usize];
        file.seek(SeekFrom::Start(m.offset)).map_err(io_err(path))?;
        file.read_exact(&mut bytes).map_err(io_err(path))?;
        let name = path.join(format!("{key}.{}", m.suffix));
        match m.suffix.as_str() {
            "jpg" | "jpeg" | "png" => image = Some(decode_rgb(&bytes, &name)?),
            "roi.png" => roi = Some(decode_grey(&bytes, &name)?),
            "json" => {
                meta = Some(
                    serde_json::from_slice(&bytes).map_err(|e| ReadError::Format {
                        path: name.clone(),
                        reason: e.to_string(),
                    })?,
                )
            }
            s => {
                if let Some(k) = s
                    .strip_prefix("mask_")
                    .and_then(|r| r.strip_suffix(".png"))
                    .and_then(|k| k.parse().ok())
                {
                    masks.push((k, decode_grey(&bytes, &name)?));
                }
            }
        }
    }
    let image = image.ok_or_else(|| ReadError::Format {
        path: path.to_path_buf(),
        reason: format!("sample {key} has no image member"),
    })?;
    masks.sort_by_key(|(k, _)| *k);
    for (k, m) in &masks {
        check_size(
            &path.join(format!("{key}.mask_{k:02}.png")),
            m.dimensions(),
            image.dimensions(),
        )?;
    }
    Ok(Sample {
        key: key.to_string(),
        image,
        masks: masks.into_iter().map(|(_, m)| m).collect(),
        roi,
        meta,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A damaged header the property tests found: the tar reader's error
    /// quotes its name, newlines and all, which made a message of several
    /// lines.
    #[test]
    fn errors_about_damaged_headers_are_one_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("shard-000000.tar");
        let mut header = [0u8; 1024];
        header[..5].copy_from_slice(b"a\nb\rc");
        header[148..156].copy_from_slice(b"zzzzzzz\0");
        std::fs::write(&path, header).unwrap();
        let err = Dataset::open(&path).unwrap_err().to_string();
        assert!(!err.contains('\n') && !err.contains('\r'), "{err:?}");
        assert!(err.contains("a\\nb\\rc"), "{err}");
    }

    #[test]
    fn mask_names_of_both_layouts() {
        assert_eq!(mask_index("mask0.png"), Some(0));
        assert_eq!(mask_index("mask12.png"), Some(12));
        assert_eq!(mask_index("mask001.png"), Some(1));
        assert_eq!(mask_index("maskX.png"), None);
        assert_eq!(mask_index("mask0.jpg"), None);
    }

    #[test]
    fn targets_follow_the_training_interpretation() {
        let image = RgbImage::new(3, 1);
        let a = GrayImage::from_raw(3, 1, vec![200, 5, 0]).unwrap();
        let b = GrayImage::from_raw(3, 1, vec![50, 4, 0]).unwrap();
        let s = Sample {
            key: "x".into(),
            image,
            masks: vec![a, b],
            roi: None,
            meta: None,
        };
        let t = s.targets();
        assert_eq!(t.roi.data, vec![1.0, 0.0, 0.0]);
        assert!((t.weights[0].data[0] - 0.8).abs() < 1e-6);
        assert!((t.weights[1].data[0] - 0.2).abs() < 1e-6);
        assert!((t.weights[0].data[1] - 5.0 / 9.0).abs() < 1e-6);
        assert_eq!(t.weights[0].data[2], 0.0);
    }

    #[test]
    fn an_encoded_sample_decodes_as_its_written_folder_reads() {
        let image = RgbImage::from_fn(8, 6, |x, y| image::Rgb([x as u8 * 30, y as u8 * 40, 7]));
        let annotation = matseg_scene::QuantisedAnnotation {
            masks: vec![vec![255; 48], vec![0; 48]],
            background: vec![0; 48],
            roi: vec![255; 48],
        };
        let meta = crate::SampleMeta::new("2d", 3, 12, Vec::new(), serde_json::json!({"a": 1}));
        let encoded = crate::encode_sample(12, &image, &annotation, &meta);
        let decoded = decode_encoded(&encoded).unwrap();
        let dir = tempfile::tempdir().unwrap();
        crate::folders::write_sample(dir.path(), &encoded).unwrap();
        let read = Dataset::open(dir.path()).unwrap().get(0).unwrap();
        assert_eq!(decoded.key, "00000012");
        assert_eq!(decoded.key, read.key);
        assert_eq!(decoded.image, read.image);
        assert_eq!(decoded.masks, read.masks);
        assert_eq!(decoded.roi, read.roi);
        assert_eq!(decoded.meta, read.meta);
        assert_eq!(decoded.meta.unwrap()["index"], 12);
    }
}
