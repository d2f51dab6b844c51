//! Property tests of the WebDataset shards a dataset is read from
//! (`Dataset::open` on a `.tar` file or a folder of them, then
//! `Dataset::get`), and of `index_tar` and `read_tar_member` under them.
//!
//! Samples made at random (image, soft masks, ROI, sidecar) and written
//! by the crate's shard writer read back as written: the pixels of the
//! JPEG written, the masks and ROI exactly, the same sidecar. Whatever a
//! shard holds instead (arbitrary bytes, a valid shard cut short or with
//! bits flipped, a member whose header claims any size), opening it and
//! reading each sample gives samples or one-line errors naming the file,
//! never a panic, and indexing it allocates no more than a small multiple
//! of the file (a counting allocator measures it), whatever size a header
//! claims. A shard cut inside a member's data is an error.

#[path = "../../../testing/properties.rs"]
mod support;

use support::{mutate, mutation, position};

use image::{GrayImage, RgbImage};
use matseg_data::wds::{shard_path, ShardWriter};
use matseg_data::{
    decode_encoded, encode_sample, index_tar, read_tar_member, Dataset, EncodedSample, SampleMeta,
};
use matseg_scene::QuantisedAnnotation;
use proptest::prelude::*;
use serde_json::Value;
use std::path::Path;
use support::allocations;

#[global_allocator]
static ALLOCATOR: allocations::Counting = allocations::Counting;

/// The seed of the cases.
const SEED: u64 = 4;

fn config() -> ProptestConfig {
    support::config(SEED)
}

// ---------------------------------------------------------------- inputs

/// Any JSON value, a few levels deep.
fn json_value() -> impl Strategy<Value = Value> {
    let numbers = prop_oneof![
        any::<i64>().prop_map(Value::from),
        any::<f64>().prop_map(Value::from),
    ];
    support::json_value(numbers, 3, 4)
}

/// One sample as a generator makes it, before encoding: an image of a
/// few pixels, its masks and ROI, its sidecar.
#[derive(Clone, Debug)]
struct Made {
    index: u64,
    image: RgbImage,
    annotation: QuantisedAnnotation,
    meta: SampleMeta,
}

impl Made {
    fn encoded(&self) -> EncodedSample {
        encode_sample(self.index, &self.image, &self.annotation, &self.meta)
    }
}

fn sample(index: u64) -> impl Strategy<Value = Made> {
    (1u32..12, 1u32..12, 0usize..4).prop_flat_map(move |(w, h, k)| {
        let n = (w * h) as usize;
        let plane = move || prop::collection::vec(any::<u8>(), n);
        (
            prop::collection::vec(any::<u8>(), n * 3),
            prop::collection::vec(plane(), k),
            plane(),
            ("2d|3d", any::<u64>(), json_value()),
        )
            .prop_map(move |(pixels, masks, roi, (kind, seed, scene))| Made {
                index,
                image: RgbImage::from_raw(w, h, pixels).expect("w * h * 3 bytes"),
                annotation: QuantisedAnnotation {
                    masks,
                    background: vec![0; n],
                    roi,
                },
                meta: SampleMeta::new(&kind, seed, index, Vec::new(), scene),
            })
    })
}

/// Samples of increasing indices, from any first one.
fn samples() -> impl Strategy<Value = Vec<Made>> {
    (0u64..1000, 1usize..4)
        .prop_flat_map(|(first, n)| (0..n).map(|k| sample(first + k as u64)).collect::<Vec<_>>())
}

/// Writes `samples` as shard 0 of `dir`; its path.
fn write_shard(dir: &Path, samples: &[Made]) -> std::path::PathBuf {
    let path = shard_path(dir, 0);
    let mut writer = ShardWriter::create(path.clone()).unwrap();
    for s in samples {
        writer.append(&s.encoded()).unwrap();
    }
    writer.finish().unwrap();
    path
}

/// Where each member's header is in a tar of `bytes`.
fn headers(bytes: &[u8]) -> Vec<usize> {
    let mut at = 0;
    let mut out = Vec::new();
    while at + 512 <= bytes.len() && bytes[at] != 0 {
        out.push(at);
        let size = std::str::from_utf8(&bytes[at + 124..at + 135]).unwrap();
        let size = usize::from_str_radix(size.trim_matches(['\0', ' ']), 8).unwrap();
        at += 512 + size.div_ceil(512) * 512;
    }
    out
}

/// Sets the size field of the header at `at` to `size` (octal when it
/// fits, else base-256) and its checksum to match.
fn set_size(bytes: &mut [u8], at: usize, size: u64) {
    let field = &mut bytes[at + 124..at + 136];
    if size < 8u64.pow(11) {
        field.copy_from_slice(format!("{size:011o}\0").as_bytes());
    } else {
        field[..4].copy_from_slice(&[0x80, 0, 0, 0]);
        field[4..].copy_from_slice(&size.to_be_bytes());
    }
    bytes[at + 148..at + 156].copy_from_slice(b"        ");
    let sum: u32 = bytes[at..at + 512].iter().map(|&b| b as u32).sum();
    bytes[at + 148..at + 156].copy_from_slice(format!("{sum:06o}\0 ").as_bytes());
}

/// Opens `path` as a dataset and reads every sample: no panic, one-line
/// errors naming the file, and indexing bounded by the file's size.
fn read_any(path: &Path) -> Result<(), TestCaseError> {
    let len = std::fs::metadata(path).unwrap().len() as usize;
    let (opened, held) = allocations::peak(|| Dataset::open(path));
    prop_assert!(held <= 64 * len + (1 << 20), "indexing held {} bytes", held);
    // A decoder's message may end in a newline (the JPEG decoder's do,
    // and image errors keep them); no other is allowed.
    let one_line = |e: &dyn std::fmt::Display| -> Result<(), TestCaseError> {
        let text = e.to_string();
        prop_assert!(!text.contains('\n'), "{:?}", text);
        prop_assert!(text.starts_with(&path.display().to_string()), "{}", text);
        Ok(())
    };
    match opened {
        Ok(dataset) => {
            for sample in dataset.iter() {
                if let Err(e) = sample {
                    one_line(&e)?;
                }
            }
        }
        Err(e) => one_line(&e)?,
    }
    match index_tar(path) {
        Ok(members) => {
            for m in &members {
                prop_assert!(m.offset + m.size <= len as u64);
                prop_assert_eq!(read_tar_member(path, m).unwrap().len() as u64, m.size);
            }
        }
        Err(e) => one_line(&e)?,
    }
    Ok(())
}

// ---------------------------------------------------------------- properties

proptest! {
    #![proptest_config(config())]

    #[test]
    fn samples_read_back_as_written(samples in samples()) {
        let dir = tempfile::tempdir().unwrap();
        let path = write_shard(dir.path(), &samples);
        for root in [path.as_path(), dir.path()] {
            let dataset = Dataset::open(root).unwrap();
            prop_assert_eq!(dataset.len(), samples.len());
            for (i, made) in samples.iter().enumerate() {
                let read = dataset.get(i).unwrap();
                let (w, h) = made.image.dimensions();
                let plane = |data: &Vec<u8>| GrayImage::from_raw(w, h, data.clone()).unwrap();
                prop_assert_eq!(&read.key, &format!("{:08}", made.index));
                prop_assert_eq!(&read.image, &decode_encoded(&made.encoded()).unwrap().image);
                let masks: Vec<GrayImage> = made.annotation.masks.iter().map(plane).collect();
                prop_assert_eq!(&read.masks, &masks);
                prop_assert_eq!(read.roi.as_ref(), Some(&plane(&made.annotation.roi)));
                prop_assert_eq!(read.meta, Some(serde_json::to_value(&made.meta).unwrap()));
            }
        }
    }

    #[test]
    fn shards_cut_inside_a_member_are_errors(samples in samples(), share in any::<u16>()) {
        let dir = tempfile::tempdir().unwrap();
        let path = write_shard(dir.path(), &samples);
        let bytes = std::fs::read(&path).unwrap();
        // A cut inside the data of a member (past its header, before its
        // last byte).
        let members = index_tar(&path).unwrap();
        let filled: Vec<_> = members.iter().filter(|m| m.size > 0).collect();
        let m = filled[position(share, filled.len())];
        let cut = m.offset as usize + position(share, m.size as usize);
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let err = Dataset::open(&path).unwrap_err().to_string();
        prop_assert!(err.contains("truncated"), "{}", err);
        read_any(&path)?;
    }

    #[test]
    fn damaged_shards_never_panic(samples in samples(), m in mutation()) {
        let dir = tempfile::tempdir().unwrap();
        let path = write_shard(dir.path(), &samples);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, mutate(&bytes, &m)).unwrap();
        read_any(&path)?;
    }

    #[test]
    fn member_sizes_that_lie_never_panic(
        samples in samples(),
        which in any::<prop::sample::Index>(),
        size in prop_oneof![
            0u64..4096,
            any::<u64>(),
            Just(u64::MAX),
            Just(8u64.pow(11) - 1),
            Just(1 << 40),
        ],
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = write_shard(dir.path(), &samples);
        let mut bytes = std::fs::read(&path).unwrap();
        let at = headers(&bytes);
        set_size(&mut bytes, at[which.index(at.len())], size);
        std::fs::write(&path, &bytes).unwrap();
        read_any(&path)?;
    }

    #[test]
    fn shards_of_arbitrary_bytes_never_panic(
        bytes in prop::collection::vec(any::<u8>(), 0..2048),
        header in any::<bool>(),
    ) {
        // Half of them begin with a valid header of a member as large as
        // the rest, so the reader goes on into the member and past it.
        let mut bytes = bytes;
        if header && bytes.len() >= 512 {
            let name = b"00000000.jpg";
            bytes[..512].fill(0);
            bytes[..name.len()].copy_from_slice(name);
            bytes[257..263].copy_from_slice(b"ustar\0");
            bytes[263..265].copy_from_slice(b"00");
            bytes[156] = b'0';
            let rest = (bytes.len() - 512) as u64;
            set_size(&mut bytes, 0, rest);
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("shard-000000.tar");
        std::fs::write(&path, &bytes).unwrap();
        read_any(&path)?;
    }
}
