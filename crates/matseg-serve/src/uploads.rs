//! Uploads: the photos and videos the pages send, written to the server's
//! folder as their bytes arrive (never whole in memory), each within its
//! own cap, and all of them together, arriving and kept, within one bound
//! on disk. When a new upload needs room, the least recently used ones
//! go, except those in use (a video being tracked, a photo being read).

use crate::app::ApiError;
use crate::roots::plain_name;
use axum::body::{Body, HttpBody};
use axum::http::StatusCode;
use http_body_util::BodyExt;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use tokio::io::AsyncWriteExt;

/// The uploads folder and its bound.
pub struct UploadFolder {
    dir: PathBuf,
    limit: u64,
    state: Mutex<State>,
}

/// What the folder holds.
#[derive(Default)]
struct State {
    /// Kept uploads by name.
    kept: HashMap<String, Kept>,
    /// Bytes kept.
    kept_bytes: u64,
    /// Bytes received so far by uploads still arriving.
    arriving_bytes: u64,
    /// Counts uses, for least recently used first out.
    clock: u64,
    /// Names arriving files apart.
    arrivals: u64,
}

struct Kept {
    file: PathBuf,
    bytes: u64,
    used: u64,
    /// Held by every [`Upload`] handed out; a kept upload whose hold is
    /// shared is in use and stays.
    hold: Arc<()>,
}

/// A kept upload, in use (not removed) while this is held.
#[derive(Clone, Debug)]
pub struct Upload {
    /// Its file.
    pub file: PathBuf,
    _hold: Arc<()>,
}

/// An upload whose bytes are all on disk, not yet checked and kept: its
/// file and bytes are given up when it is dropped.
pub struct Arrived<'a> {
    folder: &'a UploadFolder,
    /// The file holding its bytes.
    pub file: PathBuf,
    /// How many bytes.
    pub bytes: u64,
    /// FNV-1a of its bytes (the same for the same bytes).
    pub hash: u64,
    kept: bool,
}

impl UploadFolder {
    /// An empty uploads folder `dir` (made now), holding at most `limit`
    /// bytes of uploads, arriving and kept.
    pub fn new(dir: PathBuf, limit: u64) -> std::io::Result<Self> {
        std::fs::create_dir_all(&dir)?;
        Ok(Self {
            dir,
            limit,
            state: Mutex::default(),
        })
    }

    fn state(&self) -> std::sync::MutexGuard<'_, State> {
        matseg_image::sync::lock(&self.state)
    }

    /// The bound, in bytes.
    pub fn limit(&self) -> u64 {
        self.limit
    }

    /// Bytes on disk now: kept and arriving.
    pub fn bytes(&self) -> u64 {
        let state = self.state();
        state.kept_bytes + state.arriving_bytes
    }

    /// The kept upload `name`, in use while the answer is held.
    pub fn get(&self, name: &str) -> Option<Upload> {
        let mut state = self.state();
        state.clock += 1;
        let now = state.clock;
        state.kept.get_mut(name).map(|kept| {
            kept.used = now;
            Upload {
                file: kept.file.clone(),
                _hold: kept.hold.clone(),
            }
        })
    }

    /// The names of the kept uploads that `keep` says are of a kind (e.g.
    /// videos), sorted.
    pub fn names(&self, keep: impl Fn(&str) -> bool) -> Vec<String> {
        let mut names: Vec<String> = self
            .state()
            .kept
            .keys()
            .filter(|n| keep(n))
            .cloned()
            .collect();
        names.sort();
        names
    }

    /// Reads `body` into a new file as it arrives: 413 when it is larger
    /// than `cap` bytes or than the folder's whole bound (`what` names it;
    /// at once when its length is declared, else once it passes), 507
    /// when the bound leaves no room even with every unused upload
    /// removed. Nothing is left behind when it fails. A client reads the
    /// answer only once it has sent its body, so the rest of a body
    /// refused as larger than the bound is read and dropped, up to `cap`.
    pub async fn receive(
        &self,
        mut body: Body,
        cap: u64,
        what: &str,
    ) -> Result<Arrived<'_>, ApiError> {
        if let Some(declared) = body.size_hint().exact() {
            if let Err(refused) = self.check_size(declared, true, cap, what) {
                if declared <= cap {
                    discard(&mut body, cap).await;
                }
                return Err(refused);
            }
        }
        let file = {
            let mut state = self.state();
            state.arrivals += 1;
            self.dir.join(format!(".arriving-{}", state.arrivals))
        };
        let mut arrived = Arrived {
            folder: self,
            file,
            bytes: 0,
            hash: FNV_OFFSET,
            kept: false,
        };
        let failed =
            |e: std::io::Error| ApiError::internal(format!("{what}: cannot be written: {e}"));
        let mut out = tokio::fs::File::create(&arrived.file)
            .await
            .map_err(failed)?;
        while let Some(frame) = body.frame().await {
            let frame =
                frame.map_err(|e| ApiError::bad(format!("{what}: the upload broke off: {e}")))?;
            let Ok(chunk) = frame.into_data() else {
                continue;
            };
            let size = chunk.len() as u64;
            if let Err(refused) = self.check_size(arrived.bytes + size, false, cap, what) {
                discard(&mut body, cap.saturating_sub(arrived.bytes + size)).await;
                return Err(refused);
            }
            self.reserve(size, what)?;
            arrived.bytes += size;
            arrived.hash = fnv1a(arrived.hash, &chunk);
            out.write_all(&chunk).await.map_err(failed)?;
        }
        out.flush().await.map_err(failed)?;
        Ok(arrived)
    }

    /// A 413 when `bytes` (the whole upload when `whole`, else what has
    /// arrived so far) is more than `cap` or than the folder's bound: an
    /// upload no room could ever be made for.
    fn check_size(&self, bytes: u64, whole: bool, cap: u64, what: &str) -> Result<(), ApiError> {
        let mib = |bytes: u64| bytes as f64 / (1 << 20) as f64;
        let size = if whole {
            format!("{:.1} MiB ({bytes} bytes)", mib(bytes))
        } else {
            format!("at least {:.1} MiB", mib(bytes))
        };
        let message = if bytes > cap && cap <= self.limit {
            format!(
                "{what} of {size}: larger than {}, the most one may have",
                mib_text(cap)
            )
        } else if bytes > self.limit {
            format!(
                "{what} of {size}: larger than the server's whole bound on uploads, {} (--upload-mb)",
                mib_text(self.limit)
            )
        } else {
            return Ok(());
        };
        Err(ApiError::new(StatusCode::PAYLOAD_TOO_LARGE, message))
    }

    /// Counts `bytes` more arriving, removing the least recently used
    /// unused uploads while they would pass the bound.
    fn reserve(&self, bytes: u64, what: &str) -> Result<(), ApiError> {
        let mut state = self.state();
        while state.kept_bytes + state.arriving_bytes + bytes > self.limit {
            let oldest = state
                .kept
                .iter()
                .filter(|(_, k)| Arc::strong_count(&k.hold) == 1)
                .min_by_key(|(_, k)| k.used)
                .map(|(name, _)| name.clone());
            let Some(name) = oldest else {
                return Err(ApiError::new(
                    StatusCode::INSUFFICIENT_STORAGE,
                    format!(
                        "{what}: the server's uploads are full ({} MiB, --upload-mb); wait for a track to finish",
                        self.limit >> 20
                    ),
                ));
            };
            let kept = state.kept.remove(&name).expect("found above");
            state.kept_bytes -= kept.bytes;
            let _ = std::fs::remove_file(&kept.file);
        }
        state.arriving_bytes += bytes;
        Ok(())
    }
}

impl Arrived<'_> {
    /// Keeps the upload under `name` (a file name without folders),
    /// replacing an upload of that name; in use while the answer is held.
    pub fn keep(mut self, name: &str) -> Result<Upload, ApiError> {
        let folder = self.folder;
        let file = folder.dir.join(plain_name(name)?);
        let mut state = folder.state();
        std::fs::rename(&self.file, &file)
            .map_err(|e| ApiError::internal(format!("{name}: cannot be kept: {e}")))?;
        self.kept = true;
        state.arriving_bytes -= self.bytes;
        state.clock += 1;
        let kept = Kept {
            file: file.clone(),
            bytes: self.bytes,
            used: state.clock,
            hold: Arc::new(()),
        };
        let upload = Upload {
            file,
            _hold: kept.hold.clone(),
        };
        if let Some(old) = state.kept.insert(name.to_string(), kept) {
            state.kept_bytes -= old.bytes;
        }
        state.kept_bytes += self.bytes;
        Ok(upload)
    }
}

impl Drop for Arrived<'_> {
    fn drop(&mut self) {
        if !self.kept {
            let _ = std::fs::remove_file(&self.file);
            self.folder.state().arriving_bytes -= self.bytes;
        }
    }
}

/// Reads what is left of `body` and drops it, `most` bytes at most.
async fn discard(body: &mut Body, most: u64) {
    let mut read = 0u64;
    while read <= most {
        match body.frame().await {
            Some(Ok(frame)) => read += frame.data_ref().map_or(0, |d| d.len() as u64),
            _ => break,
        }
    }
}

/// `bytes` in MiB as a bound is given: whole MiB when it is one.
fn mib_text(bytes: u64) -> String {
    if bytes.is_multiple_of(1 << 20) {
        format!("{} MiB", bytes >> 20)
    } else {
        format!("{:.1} MiB", bytes as f64 / (1 << 20) as f64)
    }
}

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a over `bytes`, continuing from `hash`.
fn fnv1a(hash: u64, bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(hash, |h, &b| (h ^ b as u64).wrapping_mul(0x0100_0000_01b3))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn body(bytes: &[u8]) -> Body {
        Body::from(bytes.to_vec())
    }

    fn files(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[tokio::test]
    async fn uploads_are_kept_within_the_bound_oldest_unused_first_out() {
        let dir = tempfile::tempdir().unwrap();
        let folder = UploadFolder::new(dir.path().join("uploads"), 100).unwrap();
        let a = folder.receive(body(&[1; 40]), 50, "a").await.unwrap();
        assert_eq!((a.bytes, folder.bytes()), (40, 40));
        let a = a.keep("a").unwrap();
        drop(a);
        let b = folder
            .receive(body(&[2; 40]), 50, "b")
            .await
            .unwrap()
            .keep("b")
            .unwrap();
        // 40 + 40 kept, 30 more arriving: the oldest unused (a) goes.
        let c = folder.receive(body(&[3; 30]), 50, "c").await.unwrap();
        assert!(folder.get("a").is_none());
        assert_eq!(folder.bytes(), 70);
        drop(c);
        assert_eq!(folder.bytes(), 40);
        assert_eq!(files(&dir.path().join("uploads")), ["b"]);
        // b in use: no room for 70 more.
        let refused = folder.receive(body(&[4; 70]), 80, "d").await.err().unwrap();
        assert_eq!(refused.status(), StatusCode::INSUFFICIENT_STORAGE);
        assert_eq!(folder.bytes(), 40);
        assert_eq!(files(&dir.path().join("uploads")), ["b"]);
        drop(b);
        let d = folder
            .receive(body(&[4; 70]), 80, "d")
            .await
            .unwrap()
            .keep("d")
            .unwrap();
        assert_eq!(std::fs::read(&d.file).unwrap(), vec![4; 70]);
        assert_eq!(folder.names(|_| true), ["d"]);
        // Over the cap: 413, nothing left.
        let big = folder.receive(body(&[5; 81]), 80, "e").await.err().unwrap();
        assert_eq!(big.status(), StatusCode::PAYLOAD_TOO_LARGE);
        assert_eq!(files(&dir.path().join("uploads")), ["d"]);
        assert_eq!(folder.bytes(), 70);
    }

    #[tokio::test]
    async fn an_upload_larger_than_the_whole_bound_is_too_large_not_out_of_room() {
        let dir = tempfile::tempdir().unwrap();
        let limit = 5 << 20;
        let folder = UploadFolder::new(dir.path().to_path_buf(), limit).unwrap();
        let bytes = vec![7; 7_235_174];
        let declared = folder.receive(body(&bytes), 32 << 20, "upload").await;
        let refused = declared.err().unwrap();
        assert_eq!(refused.status(), StatusCode::PAYLOAD_TOO_LARGE);
        assert_eq!(
            refused.message(),
            "upload of 6.9 MiB (7235174 bytes): larger than the server's whole bound on uploads, 5 MiB (--upload-mb)"
        );
        // Its length not declared: refused once it passes the bound.
        let streamed = Body::from_stream(body(&bytes).into_data_stream());
        let refused = folder
            .receive(streamed, 32 << 20, "upload")
            .await
            .err()
            .unwrap();
        assert_eq!(refused.status(), StatusCode::PAYLOAD_TOO_LARGE);
        assert!(
            refused.message().starts_with("upload of at least 6.9 MiB: larger than the server's whole bound on uploads, 5 MiB"),
            "{}",
            refused.message()
        );
        // Past its own cap, the cap is named.
        let refused = folder
            .receive(body(&[1; 81]), 80, "upload")
            .await
            .err()
            .unwrap();
        assert_eq!(refused.status(), StatusCode::PAYLOAD_TOO_LARGE);
        assert_eq!(
            refused.message(),
            "upload of 0.0 MiB (81 bytes): larger than 0.0 MiB, the most one may have"
        );
        assert_eq!(folder.bytes(), 0);
        assert_eq!(files(dir.path()), Vec::<String>::new());
    }

    #[tokio::test]
    async fn the_same_bytes_hash_alike_and_a_name_is_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let folder = UploadFolder::new(dir.path().to_path_buf(), 1000).unwrap();
        let one = folder.receive(body(b"photo"), 100, "a").await.unwrap();
        let two = folder.receive(body(b"photo"), 100, "b").await.unwrap();
        assert_eq!(one.hash, two.hash);
        assert_eq!(one.hash, fnv1a(FNV_OFFSET, b"photo"));
        one.keep("x").unwrap();
        two.keep("x").unwrap();
        assert_eq!(folder.bytes(), 5);
        assert_eq!(files(dir.path()), ["x"]);
    }
}
