//! Property tests of the readers `matseg weights import` and the net feed
//! files to: safetensors, PyTorch checkpoints (the pickle reader, the
//! legacy layout and the zip one) and the zip reader under them.
//!
//! Whatever the bytes (arbitrary, a valid file truncated or with bits
//! flipped, a header or directory whose lengths, sizes and offsets lie,
//! pickles nested or referencing their memo without end), a reader returns
//! a value or a one-line error: it never panics, and it never allocates
//! much more than the file it reads (a counting allocator measures each
//! read), so a declared size is checked before anything of that size is
//! made. Valid files, written by this crate or byte by byte as `torch.save`
//! lays them out, read back to what was written.

#[path = "../../../testing/properties.rs"]
mod support;

use support::{mutate, mutation, position};

use matseg_weights::fixtures::{floats, legacy, zipped, Storage, View};
use matseg_weights::pickle::read_pickle;
use matseg_weights::zip::{write_stored, ZipArchive, ZipFile};
use matseg_weights::{
    read_checkpoint, read_safetensors, read_safetensors_metadata, write_safetensors, DType, Tensor,
};
use proptest::prelude::*;
use serde_json::{json, Value};
use std::collections::{BTreeMap, BTreeSet};
use support::allocations;

#[global_allocator]
static ALLOCATOR: allocations::Counting = allocations::Counting;

/// The most a read of `len` bytes may hold at once: a small multiple of
/// the file (parsed headers take more than their text) and a little more.
fn budget(len: usize) -> usize {
    64 * len + (1 << 20)
}

/// The most a pickle read of `len` bytes may hold at once: each byte may
/// make a value (a few dozen bytes) on the reader's stack, and the memo
/// may copy values up to the reader's allowance.
fn pickle_budget(len: usize) -> usize {
    256 * len + matseg_weights::pickle::MEMO_COPY_ALLOWANCE + (64 << 20)
}

/// The seed of the cases.
const SEED: u64 = 1;

fn config() -> ProptestConfig {
    support::config(SEED)
}

/// Runs `read`, failing the property when it held more than `limit` bytes.
fn bounded<T>(limit: usize, read: impl FnOnce() -> T) -> Result<T, TestCaseError> {
    let (out, held) = allocations::peak(read);
    prop_assert!(held <= limit, "held {held} bytes at once, over {limit}");
    Ok(out)
}

/// An error of a reader is one line.
fn one_line(error: &impl std::fmt::Display) -> Result<(), TestCaseError> {
    let text = error.to_string();
    prop_assert!(
        !text.contains('\n'),
        "a message of more than one line: {text:?}"
    );
    Ok(())
}

// ---------------------------------------------------------------- safetensors

const DTYPES: [DType; 10] = DType::ALL;

/// Tensors with distinct names (none `__metadata__`), small shapes and
/// bytes of the right length.
fn tensors() -> impl Strategy<Value = Vec<Tensor>> {
    let tensor = (
        any::<String>(),
        0..DTYPES.len(),
        prop::collection::vec(0usize..5, 0..4),
    )
        .prop_flat_map(|(name, dtype, shape)| {
            let dtype = DTYPES[dtype];
            let len = shape.iter().product::<usize>() * dtype.size();
            prop::collection::vec(any::<u8>(), len).prop_map(move |data| Tensor {
                name: name.clone(),
                dtype,
                shape: shape.clone(),
                data,
            })
        });
    prop::collection::vec(tensor, 0..6).prop_map(|mut tensors| {
        for (i, t) in tensors.iter_mut().enumerate() {
            t.name = format!("{i}.{}", t.name);
        }
        tensors
    })
}

fn metadata() -> impl Strategy<Value = BTreeMap<String, String>> {
    prop::collection::btree_map(any::<String>(), any::<String>(), 0..4)
}

/// A valid safetensors file.
fn safetensors_file() -> impl Strategy<Value = Vec<u8>> {
    (tensors(), metadata()).prop_map(|(tensors, meta)| {
        let meta: Vec<(&str, &str)> = meta.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
        write_safetensors(&tensors, &meta)
    })
}

/// Numbers a header may hold: small, near the limits of the integer
/// types, negative, fractional.
fn json_number() -> impl Strategy<Value = Value> {
    prop_oneof![
        (0u64..80).prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        prop::sample::select(vec![
            u64::MAX,
            u64::MAX - 7,
            1 << 63,
            1 << 62,
            1 << 60,
            1 << 32,
            u32::MAX as u64,
        ])
        .prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        (-1e20f64..1e20).prop_map(Value::from),
    ]
}

/// Any JSON value, a few levels deep.
fn json_value() -> impl Strategy<Value = Value> {
    support::json_value(json_number(), 3, 6)
}

/// A header entry of plausible shape with any values: known and unknown
/// type names, shapes and offsets of any numbers, fields missing or of
/// another type.
fn header_entry() -> impl Strategy<Value = Value> {
    let dtype = prop_oneof![
        prop::sample::select(DTYPES.map(DType::safetensors_name).to_vec()).prop_map(Value::from),
        json_value(),
    ];
    let numbers = || prop::collection::vec(json_number(), 0..5).prop_map(Value::Array);
    // Offsets that fit the data most often, so the shape is what is tried.
    let within = (0u64..64, 0u64..64).prop_map(|(a, b)| json!([a.min(b), a.max(b)]));
    (
        dtype,
        prop_oneof![3 => numbers(), 1 => json_value()],
        prop_oneof![3 => within, 1 => numbers(), 1 => json_value()],
        any::<u8>(),
    )
        .prop_map(|(dtype, shape, offsets, drop)| {
            let mut entry = json!({"dtype": dtype, "shape": shape, "data_offsets": offsets});
            let object = entry.as_object_mut().expect("an object");
            for (bit, key) in ["dtype", "shape", "data_offsets"].iter().enumerate() {
                if drop & (1 << bit) != 0 && drop & 0x80 != 0 {
                    object.remove(*key);
                }
            }
            entry
        })
}

/// A file whose header is made of [`header_entry`]s over some data bytes.
fn lying_safetensors() -> impl Strategy<Value = Vec<u8>> {
    (
        prop::collection::btree_map(any::<String>(), header_entry(), 0..5),
        prop::option::of(json_value()),
        prop::collection::vec(any::<u8>(), 0..64),
    )
        .prop_map(|(entries, meta, data)| {
            let mut header: serde_json::Map<String, Value> = entries.into_iter().collect();
            if let Some(meta) = meta {
                header.insert("__metadata__".into(), meta);
            }
            let text = serde_json::to_vec(&Value::Object(header)).expect("JSON");
            let mut out = (text.len() as u64).to_le_bytes().to_vec();
            out.extend(text);
            out.extend(data);
            out
        })
}

/// Reads `bytes` as safetensors (tensors and metadata): no panic, an
/// allocation bounded by the file, a one-line error.
fn read_any_safetensors(bytes: &[u8]) -> Result<(), TestCaseError> {
    let tensors = bounded(budget(bytes.len()), || {
        read_safetensors(bytes, "any.safetensors")
    })?;
    if let Err(e) = &tensors {
        one_line(e)?;
    }
    let metadata = bounded(budget(bytes.len()), || {
        read_safetensors_metadata(bytes, "any.safetensors")
    })?;
    if let Err(e) = &metadata {
        one_line(e)?;
    }
    if let Ok(tensors) = tensors {
        for t in tensors {
            prop_assert_eq!(
                t.data.len(),
                t.shape.iter().product::<usize>() * t.dtype.size()
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn safetensors_round_trip(tensors in tensors(), meta in metadata()) {
        let pairs: Vec<(&str, &str)> = meta.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
        let bytes = write_safetensors(&tensors, &pairs);
        let read = read_safetensors(&bytes, "t.safetensors").unwrap();
        // The same tensors; those holding bytes in the order written (empty
        // ones share an offset with a neighbour, so their place is open).
        let by_name = |ts: &[Tensor]| {
            ts.iter().map(|t| (t.name.clone(), t.clone())).collect::<BTreeMap<_, _>>()
        };
        prop_assert_eq!(by_name(&read), by_name(&tensors));
        let filled = |ts: &[Tensor]| {
            ts.iter().filter(|t| !t.data.is_empty()).map(|t| t.name.clone()).collect::<Vec<_>>()
        };
        prop_assert_eq!(filled(&read), filled(&tensors));
        let read_meta: BTreeMap<String, String> =
            read_safetensors_metadata(&bytes, "t.safetensors").unwrap().into_iter().collect();
        prop_assert_eq!(read_meta, meta);
    }

    #[test]
    fn safetensors_cut_short_are_errors(file in safetensors_file(), share in any::<u16>()) {
        // Every proper prefix, from a random one down to the first bytes.
        let cut = position(share, file.len());
        let cut = bounded(budget(file.len()), || read_safetensors(&file[..cut], "cut"))?;
        prop_assert!(cut.is_err());
        for len in 0..file.len().min(24) {
            prop_assert!(read_safetensors(&file[..len], "cut").is_err());
        }
    }

    #[test]
    fn safetensors_of_arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..256)) {
        read_any_safetensors(&bytes)?;
    }

    #[test]
    fn safetensors_header_lengths_that_lie_are_errors(
        len in prop_oneof![
            any::<u64>(),
            prop::sample::select(vec![u64::MAX, u64::MAX - 7, u64::MAX - 8, 1 << 63, 1 << 60, 1 << 32]),
        ],
        rest in prop::collection::vec(any::<u8>(), 0..64),
    ) {
        let mut bytes = len.to_le_bytes().to_vec();
        bytes.extend(&rest);
        prop_assume!(len > rest.len() as u64);
        let read = bounded(budget(bytes.len()), || read_safetensors(&bytes, "long"))?;
        prop_assert!(read.is_err());
        read_any_safetensors(&bytes)?;
    }

    #[test]
    fn safetensors_headers_that_lie_never_panic(bytes in lying_safetensors()) {
        read_any_safetensors(&bytes)?;
    }

    #[test]
    fn damaged_safetensors_never_panic(file in safetensors_file(), m in mutation()) {
        read_any_safetensors(&mutate(&file, &m))?;
    }
}

// ---------------------------------------------------------------- zip

/// Entries of distinct names and any bytes.
fn zip_entries() -> impl Strategy<Value = Vec<(String, Vec<u8>)>> {
    prop::collection::btree_map(
        any::<String>().prop_filter("names fit a u16", |n| n.len() < 200),
        prop::collection::vec(any::<u8>(), 0..96),
        0..5,
    )
    .prop_map(|m| m.into_iter().collect())
}

fn zip_file(entries: &[(String, Vec<u8>)]) -> Vec<u8> {
    let refs: Vec<(&str, &[u8])> = entries
        .iter()
        .map(|(n, d)| (n.as_str(), d.as_slice()))
        .collect();
    write_stored(&refs)
}

/// Where the numbers of a zip written by [`write_stored`] are: (offset,
/// width, whether a reader takes sizes from it) of every field of its
/// local headers, central directory entries and end record.
fn zip_fields(entries: &[(String, Vec<u8>)], len: usize) -> Vec<(usize, usize, bool)> {
    // Local header: method 8, crc 14, sizes 18 and 22, name and extra
    // lengths 26 and 28. Central entry: method 10, sizes 20 and 24, lengths
    // 28, 30 and 32, local header offset 42. End record: entry counts 8
    // and 10, directory size 12 and offset 16.
    let local = [(8, 2), (14, 4), (18, 4), (22, 4), (26, 2), (28, 2)];
    let central = [
        (10, 2),
        (20, 4),
        (24, 4),
        (28, 2),
        (30, 2),
        (32, 2),
        (42, 4),
    ];
    let end = [(8, 2), (10, 2), (12, 4), (16, 4)];
    let mut fields = Vec::new();
    let mut at = 0;
    for (name, data) in entries {
        fields.extend(local.iter().map(|&(o, w)| (at + o, w, false)));
        at += 30 + name.len() + data.len();
    }
    for (name, _) in entries {
        fields.extend(
            central
                .iter()
                .map(|&(o, w)| (at + o, w, [20, 24, 42].contains(&o))),
        );
        at += 46 + name.len();
    }
    fields.extend(end.map(|(o, w)| (at + o, w, o != 8)));
    debug_assert_eq!(at + 22, len);
    fields
}

/// A value for a field: small, the largest, any.
fn field_value() -> impl Strategy<Value = u32> {
    prop_oneof![
        0u32..64,
        Just(u32::MAX),
        Just(u32::MAX - 1),
        Just(0xffff),
        any::<u32>()
    ]
}

/// Reads every entry of `bytes` through both readers.
fn read_any_zip(bytes: &[u8]) -> Result<(), TestCaseError> {
    let limit = budget(bytes.len());
    bounded(limit, || {
        if let Ok(archive) = ZipArchive::new(bytes) {
            let names: Vec<String> = archive.names().map(str::to_string).collect();
            for name in names {
                let _ = archive.read(&name);
            }
        }
    })?;
    bounded(limit, || {
        if let Ok(mut archive) = ZipFile::new(std::io::Cursor::new(bytes)) {
            let names: Vec<String> = archive.names().map(str::to_string).collect();
            for name in names {
                let _ = archive.read(&name);
            }
        }
    })?;
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn zips_round_trip(entries in zip_entries()) {
        let bytes = zip_file(&entries);
        let archive = ZipArchive::new(&bytes).unwrap();
        let names: Vec<&str> = archive.names().collect();
        let want: Vec<&str> = entries.iter().map(|(n, _)| n.as_str()).collect();
        prop_assert_eq!(names, want);
        let mut file = ZipFile::new(std::io::Cursor::new(&bytes)).unwrap();
        for (name, data) in &entries {
            prop_assert_eq!(&archive.read(name).unwrap(), data);
            prop_assert_eq!(&file.read(name).unwrap(), data);
        }
    }

    #[test]
    fn zips_of_arbitrary_bytes_never_panic(
        bytes in prop::collection::vec(any::<u8>(), 0..256),
        end_record in any::<bool>(),
    ) {
        // Half of them end in an end-of-directory record, so the directory
        // parser is reached.
        let mut bytes = bytes;
        if end_record && bytes.len() >= 22 {
            let at = bytes.len() - 22;
            bytes[at..at + 4].copy_from_slice(b"PK\x05\x06");
        }
        read_any_zip(&bytes)?;
    }

    #[test]
    fn zips_whose_sizes_lie_never_panic(
        entries in zip_entries(),
        changes in prop::collection::vec(
            (any::<bool>(), any::<prop::sample::Index>(), field_value()),
            1..4,
        ),
        deflated in any::<bool>(),
    ) {
        let mut bytes = zip_file(&entries);
        let fields = zip_fields(&entries, bytes.len());
        // Half the changes are to a field sizes are read from.
        let sizes: Vec<_> = fields.iter().copied().filter(|f| f.2).collect();
        for (size, field, value) in changes {
            let pool = if size { &sizes } else { &fields };
            let (at, width, _) = pool[field.index(pool.len())];
            bytes[at..at + width].copy_from_slice(&value.to_le_bytes()[..width]);
        }
        if deflated {
            // Every entry deflated: its stored bytes are read as a deflate
            // stream, of the size its directory entry claims.
            for &(at, width, _) in &fields {
                let signature = at.checked_sub(10).and_then(|s| bytes.get(s..s + 4));
                if width == 2 && signature == Some(&b"PK\x01\x02"[..]) {
                    bytes[at..at + 2].copy_from_slice(&8u16.to_le_bytes());
                }
            }
        }
        read_any_zip(&bytes)?;
    }

    #[test]
    fn damaged_zips_never_panic(entries in zip_entries(), m in mutation()) {
        read_any_zip(&mutate(&zip_file(&entries), &m))?;
    }
}

// ---------------------------------------------------------------- checkpoints

const KEYS: [&str; 3] = ["0", "1", "2"];
const NAMES: [&str; 5] = ["a.weight", "a.bias", "b.weight", "b.running_mean", "c"];

/// A checkpoint: storages and the views of them a state dict holds.
#[derive(Clone, Debug)]
struct Checkpoint {
    storages: Vec<Vec<f32>>,
    views: Vec<(usize, i32, Vec<i32>, Vec<i32>)>,
}

impl Checkpoint {
    fn parts(&self) -> (Vec<Storage>, Vec<View>) {
        let storages = self
            .storages
            .iter()
            .enumerate()
            .map(|(k, values)| Storage {
                key: KEYS[k],
                values: values.clone(),
            })
            .collect();
        let views = self
            .views
            .iter()
            .enumerate()
            .map(|(k, (s, offset, shape, stride))| {
                (NAMES[k], *s, *offset, shape.clone(), stride.clone())
            })
            .collect();
        (storages, views)
    }

    fn legacy(&self) -> Vec<u8> {
        let (storages, views) = self.parts();
        legacy(&storages, &views)
    }

    fn zipped(&self) -> Vec<u8> {
        let (storages, views) = self.parts();
        zipped(&storages, &views)
    }

    /// The tensors the views make, walked element by element.
    fn tensors(&self) -> Vec<Tensor> {
        self.views
            .iter()
            .enumerate()
            .map(|(k, (s, offset, shape, stride))| {
                let count: i32 = shape.iter().product();
                let mut values = Vec::new();
                for flat in 0..count {
                    let mut rest = flat;
                    let mut at = *offset;
                    for d in (0..shape.len()).rev() {
                        at += (rest % shape[d]) * stride[d];
                        rest /= shape[d];
                    }
                    values.push(self.storages[*s][at as usize]);
                }
                Tensor {
                    name: NAMES[k].into(),
                    dtype: DType::F32,
                    shape: shape.iter().map(|&d| d as usize).collect(),
                    data: floats(&values),
                }
            })
            .collect()
    }
}

/// A valid checkpoint: each view a permuted (transposed) contiguous block
/// of its storage, at an offset; storages long enough for their views.
fn checkpoint() -> impl Strategy<Value = Checkpoint> {
    let view = (
        0..KEYS.len(),
        0i32..4,
        prop::collection::vec(0i32..4, 0..4),
        any::<prop::sample::Index>(),
    )
        .prop_map(|(s, offset, shape, order)| {
            // Strides of a row-major block whose dimensions are laid out in
            // a chosen order.
            let mut dims: Vec<usize> = (0..shape.len()).collect();
            if !dims.is_empty() {
                let by = order.index(dims.len());
                dims.rotate_left(by);
            }
            let mut stride = vec![0; shape.len()];
            let mut step = 1;
            for &d in dims.iter().rev() {
                stride[d] = step;
                step *= shape[d].max(1);
            }
            (s, offset, shape, stride)
        });
    (prop::collection::vec(view, 0..NAMES.len()), 0usize..3).prop_flat_map(|(views, extra)| {
        let lengths: Vec<usize> = (0..KEYS.len())
            .map(|s| {
                views
                    .iter()
                    .filter(|v| v.0 == s)
                    .map(|(_, offset, shape, _)| {
                        *offset as usize + shape.iter().product::<i32>() as usize
                    })
                    .max()
                    .unwrap_or(0)
                    + extra
            })
            .collect();
        // Storages no view uses are left out, as torch.save leaves them.
        let used: BTreeSet<usize> = views.iter().map(|v| v.0).collect();
        let storages = lengths
            .iter()
            .map(|&n| prop::collection::vec(-1e6f32..1e6, n))
            .collect::<Vec<_>>();
        (storages, Just(views), Just(used)).prop_map(|(storages, views, used)| {
            // Renumber the storages used from 0, as torch.save does.
            let order: Vec<usize> = used.iter().copied().collect();
            let storages = order.iter().map(|&s| storages[s].clone()).collect();
            let views = views
                .into_iter()
                .map(|(s, o, shape, stride)| {
                    (
                        order.iter().position(|&u| u == s).expect("used"),
                        o,
                        shape,
                        stride,
                    )
                })
                .collect();
            Checkpoint { storages, views }
        })
    })
}

/// A checkpoint whose views are anything: offsets, sizes and strides of
/// any 32-bit values, over storages of any length.
fn lying_checkpoint() -> impl Strategy<Value = Checkpoint> {
    let number = prop_oneof![
        -2i32..6,
        Just(i32::MAX),
        Just(i32::MIN),
        Just(1 << 30),
        any::<i32>()
    ];
    let view = (
        0..KEYS.len(),
        number.clone(),
        prop::collection::vec(number.clone(), 0..4),
        prop::collection::vec(number, 0..4),
    );
    (
        prop::collection::vec(prop::collection::vec(-1e6f32..1e6, 0..8), KEYS.len()),
        prop::collection::vec(view, 0..NAMES.len()),
    )
        .prop_map(|(storages, views)| Checkpoint { storages, views })
}

/// Reads `bytes` as a checkpoint: no panic, bounded allocation, a one-line
/// error.
fn read_any_checkpoint(bytes: &[u8]) -> Result<(), TestCaseError> {
    let read = bounded(pickle_budget(bytes.len()), || {
        read_checkpoint(bytes, "any.pth")
    })?;
    if let Err(e) = &read {
        one_line(e)?;
    }
    Ok(())
}

/// Pieces of pickles: every opcode the reader knows, with operands.
fn pickle_piece() -> impl Strategy<Value = Vec<u8>> {
    let small = || 0u8..4;
    prop_oneof![
        prop::sample::select(
            [
                "N", "\u{88}", "\u{89}", "(", ")", "]", "}", "t", "l", "d", "a", "e", "s", "u",
                "R", "b", "Q", "0", ".", "\u{85}", "\u{86}", "\u{87}", "\u{93}", "\u{94}",
                "\u{81}",
            ]
            .iter()
            .map(|s| s.chars().map(|c| c as u8).collect::<Vec<u8>>())
            .collect::<Vec<_>>()
        ),
        any::<u8>().prop_map(|v| vec![b'K', v]),
        any::<i32>().prop_map(|v| [vec![b'J'], v.to_le_bytes().to_vec()].concat()),
        any::<u16>().prop_map(|v| [vec![b'M'], v.to_le_bytes().to_vec()].concat()),
        prop::collection::vec(any::<u8>(), 0..12)
            .prop_map(|b| [vec![0x8a, b.len() as u8], b].concat()),
        any::<f64>().prop_map(|v| [vec![b'G'], v.to_be_bytes().to_vec()].concat()),
        (any::<String>(), any::<u32>(), any::<bool>()).prop_map(|(s, n, lie)| {
            let n = if lie { n } else { s.len() as u32 };
            [vec![b'X'], n.to_le_bytes().to_vec(), s.into_bytes()].concat()
        }),
        "[a-z_.]{0,8}".prop_map(|s| [vec![0x8c, s.len() as u8], s.into_bytes()].concat()),
        (
            prop::sample::select(vec![b'C', b'U']),
            prop::collection::vec(any::<u8>(), 0..8)
        )
            .prop_map(|(op, b)| [vec![op, b.len() as u8], b].concat()),
        (
            prop::collection::vec(any::<u8>(), 0..8),
            any::<u32>(),
            any::<bool>()
        )
            .prop_map(|(b, n, lie)| {
                let n = if lie { n } else { b.len() as u32 };
                [vec![b'T'], n.to_le_bytes().to_vec(), b].concat()
            }),
        ("[a-z_.]{1,12}", "[A-Za-z_]{1,12}").prop_map(|(m, n)| format!("c{m}\n{n}\n").into_bytes()),
        Just(b"ctorch._utils\n_rebuild_tensor_v2\n".to_vec()),
        Just(b"ccollections\nOrderedDict\n".to_vec()),
        Just(b"ctorch\nFloatStorage\n".to_vec()),
        small().prop_map(|i| vec![b'q', i]),
        small().prop_map(|i| vec![b'h', i]),
        small().prop_map(|i| [vec![b'r'], (i as u32).to_le_bytes().to_vec()].concat()),
        small().prop_map(|i| [vec![b'j'], (i as u32).to_le_bytes().to_vec()].concat()),
        Just(vec![0x80, 2]),
        any::<u64>().prop_map(|n| [vec![0x95], n.to_le_bytes().to_vec()].concat()),
    ]
}

/// Runs that, repeated, make a value deep or large: an opening part and a
/// closing part, each repeated as often (a tuple around the top of the
/// stack, lists in lists, a memoised value fetched twice or three times
/// and stored again), or any piece repeated.
fn pickle_run() -> impl Strategy<Value = (Vec<u8>, Vec<u8>)> {
    prop_oneof![
        2 => pickle_piece().prop_map(|piece| (Vec::new(), piece)),
        1 => Just((Vec::new(), vec![0x85])),
        1 => Just((vec![b'('], vec![b'l'])),
        1 => Just((vec![b']'], vec![b'a'])),
        1 => (0u8..8).prop_map(|i| (Vec::new(), vec![b'h', i, b'h', i, 0x86, b'q', i])),
        1 => (0u8..8).prop_map(|i| (Vec::new(), vec![b'(', b'h', i, b'h', i, b'h', i, b'l', b'q', i])),
        1 => (0u8..7).prop_map(|i| (Vec::new(), vec![b'h', i, b'q', i + 1])),
    ]
}

/// A pickle program: eight strings pushed and memoised, maybe a few
/// pieces, a run repeated many times (how deep nesting and memo bombs are
/// made), a few more pieces, and a stop.
fn pickle() -> impl Strategy<Value = Vec<u8>> {
    (
        prop_oneof![
            Just(Vec::new()),
            prop::collection::vec(pickle_piece(), 0..8)
        ],
        pickle_run(),
        prop_oneof![0usize..4, 0usize..100_000],
        prop::collection::vec(pickle_piece(), 0..4),
    )
        .prop_map(|(head, (open, close), times, tail)| {
            let mut out: Vec<u8> = Vec::new();
            for i in 0..8 {
                out.extend([b'X', 1, 0, 0, 0, b'a' + i, b'q', i]);
            }
            out.extend(head.concat());
            for _ in 0..times {
                out.extend(&open);
            }
            for _ in 0..times {
                out.extend(&close);
            }
            out.extend(tail.concat());
            out.push(b'.');
            out
        })
}

/// Where the first storage's element count is in a legacy checkpoint.
fn first_count_at(c: &Checkpoint, file: &[u8]) -> Option<usize> {
    let data: usize = c.storages.iter().map(|s| 8 + 4 * s.len()).sum();
    (!c.storages.is_empty()).then(|| file.len() - data)
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn checkpoints_in_both_formats_read_back(c in checkpoint()) {
        let want = c.tensors();
        prop_assert_eq!(read_checkpoint(&c.legacy(), "legacy.pth").unwrap(), want.clone());
        prop_assert_eq!(read_checkpoint(&c.zipped(), "zip.pth").unwrap(), want);
    }

    #[test]
    fn checkpoints_cut_short_are_errors(c in checkpoint(), share in any::<u16>()) {
        for file in [c.legacy(), c.zipped()] {
            let cut = &file[..position(share, file.len())];
            let read = bounded(pickle_budget(file.len()), || read_checkpoint(cut, "cut.pth"))?;
            let error = read.err().map(|e| e.to_string()).unwrap_or_default();
            prop_assert!(error.starts_with("cut.pth: "), "{}", error);
        }
    }

    #[test]
    fn damaged_checkpoints_never_panic(c in checkpoint(), m in mutation()) {
        read_any_checkpoint(&mutate(&c.legacy(), &m))?;
        read_any_checkpoint(&mutate(&c.zipped(), &m))?;
    }

    #[test]
    fn checkpoints_whose_views_lie_never_panic(c in lying_checkpoint()) {
        read_any_checkpoint(&c.legacy())?;
        read_any_checkpoint(&c.zipped())?;
    }

    #[test]
    fn legacy_storage_sizes_that_lie_never_panic(
        c in checkpoint(),
        count in prop_oneof![any::<i64>(), Just(i64::MAX), Just(1 << 62), Just(-1), 0i64..64],
    ) {
        let mut file = c.legacy();
        if let Some(at) = first_count_at(&c, &file) {
            file[at..at + 8].copy_from_slice(&count.to_le_bytes());
        }
        read_any_checkpoint(&file)?;
    }

    #[test]
    fn checkpoints_of_arbitrary_bytes_never_panic(
        bytes in prop::collection::vec(any::<u8>(), 0..256),
        start in prop::sample::select(vec![
            Vec::new(),
            b"PK\x03\x04".to_vec(),
            legacy(&[], &[])[..15].to_vec(),
        ]),
    ) {
        read_any_checkpoint(&[start, bytes].concat())?;
    }

    #[test]
    fn pickles_of_arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..256)) {
        let _ = bounded(pickle_budget(bytes.len()), || read_pickle(&bytes))?;
    }

    #[test]
    fn pickle_programs_never_panic(program in pickle()) {
        let read = bounded(pickle_budget(program.len()), || {
            // The value is formatted (as messages about it are) and dropped
            // here, where the allocation is counted.
            read_pickle(&program).map(|(value, used)| (format!("{value:?}").len(), used))
        })?;
        if let Ok((_, used)) = read {
            prop_assert!(used <= program.len());
        }
        // The same bytes as a legacy checkpoint's object: after the magic
        // number, protocol and system info, before the storage keys.
        let mut file = legacy(&[], &[])[..25].to_vec();
        file.extend(&program);
        file.extend([0x80, 2, b']', b'(', b'e', b'.']);
        read_any_checkpoint(&file)?;
    }
}
