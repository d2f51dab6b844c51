//! PyTorch checkpoints written byte by byte as `torch.save` lays them out
//! (legacy and zip formats), for tests across the workspace: a reader is
//! only trusted when it reads files made without it.

/// A storage of f32 values under a key.
pub struct Storage {
    /// The storage key (`"0"`, `"1"`, ...).
    pub key: &'static str,
    /// Its values.
    pub values: Vec<f32>,
}

/// A tensor view: name, storage index, offset, size, stride.
pub type View = (&'static str, usize, i32, Vec<i32>, Vec<i32>);

fn unicode(out: &mut Vec<u8>, s: &str) {
    out.push(b'X');
    out.extend((s.len() as u32).to_le_bytes());
    out.extend(s.as_bytes());
}

fn int(out: &mut Vec<u8>, v: i32) {
    out.push(b'J');
    out.extend(v.to_le_bytes());
}

fn tuple(out: &mut Vec<u8>, items: &[i32]) {
    out.push(b'(');
    for &i in items {
        int(out, i);
    }
    out.push(b't');
}

/// The state-dict pickle: an OrderedDict of `_rebuild_tensor_v2` calls.
fn state_dict_pickle(storages: &[Storage], views: &[View]) -> Vec<u8> {
    let mut p = vec![0x80, 2];
    p.extend(b"ccollections\nOrderedDict\n)R(");
    for (name, s, offset, size, stride) in views {
        unicode(&mut p, name);
        p.extend(b"ctorch._utils\n_rebuild_tensor_v2\n((");
        unicode(&mut p, "storage");
        p.extend(b"ctorch\nFloatStorage\n");
        unicode(&mut p, storages[*s].key);
        unicode(&mut p, "cpu");
        int(&mut p, storages[*s].values.len() as i32);
        p.extend(b"NtQ");
        int(&mut p, *offset);
        tuple(&mut p, size);
        tuple(&mut p, stride);
        p.push(0x89);
        p.extend(b"ccollections\nOrderedDict\n)Rt");
        p.push(b'R');
    }
    p.extend(b"u.");
    p
}

/// Little-endian bytes of `values`.
pub fn floats(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// A legacy (non-zip) `torch.save` file of the state dict `views` over `storages`.
pub fn legacy(storages: &[Storage], views: &[View]) -> Vec<u8> {
    let mut f = vec![
        0x80, 2, 0x8a, 10, 0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50, 0x19, b'.',
    ];
    f.extend([0x80, 2, b'M', 0xe9, 0x03, b'.']); // 1001
    f.extend([0x80, 2, b'}', b'.']);
    f.extend(state_dict_pickle(storages, views));
    f.extend([0x80, 2, b']', b'(']);
    for s in storages {
        unicode(&mut f, s.key);
    }
    f.extend(b"e.");
    for s in storages {
        f.extend((s.values.len() as i64).to_le_bytes());
        f.extend(floats(&s.values));
    }
    f
}

/// A zip-format `torch.save` file of the state dict `views` over `storages`.
pub fn zipped(storages: &[Storage], views: &[View]) -> Vec<u8> {
    let mut entries = vec![(
        "archive/data.pkl".to_string(),
        state_dict_pickle(storages, views),
    )];
    for s in storages {
        entries.push((format!("archive/data/{}", s.key), floats(&s.values)));
    }
    entries.push(("archive/version".into(), b"3\n".to_vec()));
    let entries: Vec<(&str, &[u8])> = entries
        .iter()
        .map(|(n, d)| (n.as_str(), d.as_slice()))
        .collect();
    crate::zip::write_stored(&entries)
}
