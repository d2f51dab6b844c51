//! Load measurement of a running server (`matseg bench-serve`): photos of
//! a chosen size to serve, a keep-alive HTTP/1.1 client on loopback, the
//! descriptor pass of each photo (its first click), clicks from concurrent
//! clients on photos already described (the server's memory is read by
//! `matseg_pipeline::bench::clock::process_memory_mib`).
//!
//! Latencies are the server's own (`Server-Timing`, the handler's time)
//! and the client's round trip; percentiles are nearest-rank.

use image::RgbImage;
use matseg_image::io::{encode_jpeg, read_rgb};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::time::{Duration, Instant};

/// A load-measurement failure: a message naming what failed.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct LoadError(pub String);

/// Writes `count` JPEG photos of about `megapixels` each into `dir`
/// (`photo000.jpg`...), made from the bundled photos (resized; every other
/// round mirrored, so no two photos of a round are the same); their sizes.
pub fn write_photos(
    dir: &Path,
    count: usize,
    megapixels: f64,
) -> Result<Vec<(String, u32, u32)>, LoadError> {
    let bundled_dir = matseg_pipeline::sources::assets_dir().join("photos");
    let bundled = matseg_image::io::find_files(&[bundled_dir], &["jpg", "png"])
        .map_err(|e| LoadError(e.to_string()))?;
    let sources: Vec<RgbImage> = bundled
        .iter()
        .map(|p| read_rgb(p).map_err(|e| LoadError(e.to_string())))
        .collect::<Result<_, _>>()?;
    if sources.is_empty() {
        return Err(LoadError(
            "no bundled photos to make load photos from".into(),
        ));
    }
    let mut written = Vec::new();
    for i in 0..count {
        let source = &sources[i % sources.len()];
        let scale = (megapixels * 1e6 / (source.width() as f64 * source.height() as f64)).sqrt();
        let (w, h) = (
            ((source.width() as f64 * scale).round() as u32).max(1),
            ((source.height() as f64 * scale).round() as u32).max(1),
        );
        let mut photo =
            image::imageops::resize(source, w, h, image::imageops::FilterType::Triangle);
        if (i / sources.len()) % 2 == 1 {
            image::imageops::flip_horizontal_in_place(&mut photo);
        }
        let name = format!("photo{i:03}.jpg");
        std::fs::write(dir.join(&name), encode_jpeg(&photo, 90))
            .map_err(|e| LoadError(format!("{}: {e}", dir.join(&name).display())))?;
        written.push((name, w, h));
    }
    Ok(written)
}

/// One answer: status, the server's milliseconds, the round trip's.
#[derive(Clone, Copy, Debug)]
pub struct Answer {
    /// HTTP status.
    pub status: u16,
    /// The server's time (its `Server-Timing`), ms.
    pub server_ms: f64,
    /// The client's round trip, ms.
    pub round_trip_ms: f64,
}

/// Where a running server is: its address (`127.0.0.1:PORT`) and the
/// token its API wants, if any.
#[derive(Clone, Debug)]
pub struct ServerAddress {
    /// `HOST:PORT`.
    pub host: String,
    /// The token API calls carry.
    pub token: Option<String>,
}

/// A keep-alive HTTP/1.1 connection to the server.
pub struct Connection {
    reader: BufReader<TcpStream>,
    server: ServerAddress,
}

impl Connection {
    /// Connects to `server`.
    pub fn open(server: &ServerAddress) -> Result<Self, LoadError> {
        let host = &server.host;
        let stream = TcpStream::connect(host).map_err(|e| LoadError(format!("{host}: {e}")))?;
        stream
            .set_nodelay(true)
            .map_err(|e| LoadError(e.to_string()))?;
        Ok(Self {
            reader: BufReader::new(stream),
            server: server.clone(),
        })
    }

    /// `GET path`, the body read and dropped.
    pub fn get(&mut self, path: &str) -> Result<Answer, LoadError> {
        self.get_body(path).map(|(answer, _)| answer)
    }

    /// `GET path` and the body.
    pub fn get_body(&mut self, path: &str) -> Result<(Answer, Vec<u8>), LoadError> {
        self.send("GET", path)
    }

    /// `METHOD path` with no body (a POST typed as JSON, as the pages send
    /// it), as the server's own page would send it: its Host, its token;
    /// the answer and its body.
    pub fn send(&mut self, method: &str, path: &str) -> Result<(Answer, Vec<u8>), LoadError> {
        let kind = (method == "POST").then_some("application/json");
        self.send_body(method, path, kind, &[])
    }

    /// `METHOD path` with `body` of type `kind`, as [`Self::send`] sends it.
    pub fn send_body(
        &mut self,
        method: &str,
        path: &str,
        kind: Option<&str>,
        body: &[u8],
    ) -> Result<(Answer, Vec<u8>), LoadError> {
        let fail = |e: std::io::Error| LoadError(format!("{method} {path}: {e}"));
        let started = Instant::now();
        let token = self
            .server
            .token
            .as_ref()
            .map(|t| format!("x-matseg-token: {t}\r\n"))
            .unwrap_or_default();
        let typed = kind
            .map(|k| format!("content-type: {k}\r\ncontent-length: {}\r\n", body.len()))
            .unwrap_or_default();
        let stream = self.reader.get_mut();
        write!(
            stream,
            "{method} {path} HTTP/1.1\r\nHost: {}\r\n{token}{typed}\r\n",
            self.server.host
        )
        .and_then(|()| stream.write_all(body))
        .map_err(fail)?;
        let mut line = String::new();
        self.reader.read_line(&mut line).map_err(fail)?;
        let status: u16 = line
            .split_whitespace()
            .nth(1)
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| LoadError(format!("{method} {path}: bad status line {line:?}")))?;
        let (mut length, mut server_ms) = (0usize, f64::NAN);
        loop {
            line.clear();
            self.reader.read_line(&mut line).map_err(fail)?;
            let header = line.trim_end();
            if header.is_empty() {
                break;
            }
            let (name, value) = header.split_once(':').unwrap_or((header, ""));
            match name.to_ascii_lowercase().as_str() {
                "content-length" => length = value.trim().parse().unwrap_or(0),
                "server-timing" => {
                    server_ms = value
                        .split("dur=")
                        .nth(1)
                        .and_then(|d| d.trim().parse().ok())
                        .unwrap_or(f64::NAN)
                }
                _ => {}
            }
        }
        let mut body = vec![0; length];
        self.reader.read_exact(&mut body).map_err(fail)?;
        let answer = Answer {
            status,
            server_ms,
            round_trip_ms: started.elapsed().as_secs_f64() * 1e3,
        };
        Ok((answer, body))
    }
}

/// The similarity request of a point on a photo of the `data0` folder.
pub fn click_path(photo: &str, x: u32, y: u32) -> String {
    format!("/api/similarity?root=data0&path={photo}&points={x},{y}")
}

/// The selection request of a click on a photo of the `data0` folder, as
/// the segment page sends it.
pub fn select_path(photo: &str, x: u32, y: u32) -> String {
    format!("/api/select?root=data0&path={photo}&positive={x},{y}")
}

/// What first clicks on photos, all sent at once, got.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct AtOnceStats {
    /// Each click's answer status (0: the request failed), in the order
    /// of the photos.
    pub statuses: Vec<u16>,
    /// Each click's round trip, ms.
    pub round_trip_ms: Vec<f64>,
    /// Seconds until the last was answered.
    pub seconds: f64,
}

/// A first click on the middle of each of `photos` (name, width, height;
/// [`select_path`]), all sent at once, each on its own connection.
pub fn first_clicks_at_once(server: &ServerAddress, photos: &[(String, u32, u32)]) -> AtOnceStats {
    let started = Instant::now();
    let answers: Vec<(u16, f64)> = std::thread::scope(|scope| {
        let clients: Vec<_> = photos
            .iter()
            .map(|(name, w, h)| {
                scope.spawn(move || {
                    let path = select_path(name, w / 2, h / 2);
                    match Connection::open(server).and_then(|mut c| c.get(&path)) {
                        Ok(answer) => (answer.status, answer.round_trip_ms),
                        Err(_) => (0, f64::NAN),
                    }
                })
            })
            .collect();
        clients
            .into_iter()
            .map(|c| c.join().unwrap_or((0, f64::NAN)))
            .collect()
    });
    AtOnceStats {
        statuses: answers.iter().map(|a| a.0).collect(),
        round_trip_ms: answers.iter().map(|a| a.1).collect(),
        seconds: started.elapsed().as_secs_f64(),
    }
}

/// Latencies of many clicks.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ClickStats {
    /// Concurrent clients.
    pub clients: usize,
    /// Answers received.
    pub requests: usize,
    /// Answers that were not 200, or requests that failed.
    pub errors: usize,
    /// Server time, median, ms.
    pub server_p50_ms: f64,
    /// Server time, 99th percentile, ms.
    pub server_p99_ms: f64,
    /// Round trip, median, ms.
    pub round_trip_p50_ms: f64,
    /// Round trip, 99th percentile, ms.
    pub round_trip_p99_ms: f64,
    /// Answers per second, all clients together.
    pub per_second: f64,
}

/// The nearest-rank `p`-th percentile of `values` (sorted here).
pub fn percentile(values: &mut [f64], p: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let rank = ((p / 100.0) * values.len() as f64).ceil() as usize;
    values[rank.clamp(1, values.len()) - 1]
}

/// `clients` clients clicking random points of random `photos` (name,
/// width, height) for `duration`, each on its own connection.
pub fn clicks(
    server: &ServerAddress,
    photos: &[(String, u32, u32)],
    clients: usize,
    duration: Duration,
) -> ClickStats {
    let started = Instant::now();
    let results: Vec<(Vec<Answer>, usize)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..clients)
            .map(|client| {
                scope.spawn(move || {
                    let mut answers = Vec::new();
                    let mut errors = 0;
                    let mut random = 0x9E37_79B9_7F4A_7C15u64
                        ^ (client as u64 + 1).wrapping_mul(0xBF58_476D_1CE4_E5B9);
                    let mut next = |n: u32| {
                        random ^= random << 13;
                        random ^= random >> 7;
                        random ^= random << 17;
                        (random % n as u64) as u32
                    };
                    let mut connection = Connection::open(server).ok();
                    while started.elapsed() < duration {
                        let (name, w, h) = &photos[next(photos.len() as u32) as usize];
                        let path = click_path(name, next(*w), next(*h));
                        match connection.as_mut().map(|c| c.get(&path)) {
                            Some(Ok(answer)) if answer.status == 200 => answers.push(answer),
                            Some(Ok(_)) => errors += 1,
                            _ => {
                                errors += 1;
                                connection = Connection::open(server).ok();
                            }
                        }
                    }
                    (answers, errors)
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|w| w.join().unwrap_or_default())
            .collect()
    });
    let seconds = started.elapsed().as_secs_f64();
    let answers: Vec<Answer> = results
        .iter()
        .flat_map(|(a, _)| a.iter().copied())
        .collect();
    let mut server: Vec<f64> = answers.iter().map(|a| a.server_ms).collect();
    let mut round_trip: Vec<f64> = answers.iter().map(|a| a.round_trip_ms).collect();
    ClickStats {
        clients,
        requests: answers.len(),
        errors: results.iter().map(|(_, e)| e).sum(),
        server_p50_ms: percentile(&mut server, 50.0),
        server_p99_ms: percentile(&mut server, 99.0),
        round_trip_p50_ms: percentile(&mut round_trip, 50.0),
        round_trip_p99_ms: percentile(&mut round_trip, 99.0),
        per_second: answers.len() as f64 / seconds,
    }
}

/// What concurrent uploads did to the server.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct UploadStats {
    /// Uploads sent at once.
    pub uploads: usize,
    /// MiB each.
    pub mib_each: f64,
    /// Each upload's answer status (0: the request failed).
    pub statuses: Vec<u16>,
    /// The server's memory (RSS) before, MiB.
    pub rss_before_mib: f64,
    /// Its highest RSS seen while they arrived (sampled every 10 ms), MiB.
    pub rss_peak_mib: f64,
    /// Its RSS once they were answered, MiB.
    pub rss_after_mib: f64,
    /// Seconds until the last was answered.
    pub seconds: f64,
}

/// `count` video uploads of `bytes_each` bytes sent at once, each `head`
/// (a small video) padded with zeros to its size, written 1 MiB at a time;
/// `rss` reads the server's memory in MiB, sampled while they arrive.
pub fn video_uploads(
    server: &ServerAddress,
    head: &[u8],
    count: usize,
    bytes_each: usize,
    rss: &(dyn Fn() -> f64 + Sync),
) -> UploadStats {
    let rss_before_mib = rss();
    let started = Instant::now();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let (statuses, rss_peak_mib) = std::thread::scope(|scope| {
        let senders: Vec<_> = (0..count)
            .map(|i| {
                let done = &done;
                scope.spawn(move || {
                    let status = upload_padded(server, &format!("load{i}.mp4"), head, bytes_each)
                        .unwrap_or(0);
                    done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    status
                })
            })
            .collect();
        let mut peak = rss_before_mib;
        while done.load(std::sync::atomic::Ordering::Relaxed) < count {
            peak = peak.max(rss());
            std::thread::sleep(Duration::from_millis(10));
        }
        let statuses: Vec<u16> = senders.into_iter().map(|s| s.join().unwrap_or(0)).collect();
        (statuses, peak)
    });
    UploadStats {
        uploads: count,
        mib_each: bytes_each as f64 / (1 << 20) as f64,
        statuses,
        rss_before_mib,
        rss_peak_mib,
        rss_after_mib: rss(),
        seconds: started.elapsed().as_secs_f64(),
    }
}

/// One video upload named `name`: `head` and zeros up to `bytes` bytes;
/// the answer's status.
fn upload_padded(
    server: &ServerAddress,
    name: &str,
    head: &[u8],
    bytes: usize,
) -> Result<u16, LoadError> {
    let fail = |e: std::io::Error| LoadError(format!("upload {name}: {e}"));
    let mut stream = TcpStream::connect(&server.host).map_err(fail)?;
    let token = server
        .token
        .as_ref()
        .map(|t| format!("x-matseg-token: {t}\r\n"))
        .unwrap_or_default();
    write!(
        stream,
        "POST /api/video/upload?name={name} HTTP/1.1\r\nHost: {}\r\n{token}content-type: video/mp4\r\ncontent-length: {bytes}\r\nconnection: close\r\n\r\n",
        server.host
    )
    .map_err(fail)?;
    stream.write_all(head).map_err(fail)?;
    let zeros = vec![0u8; 1 << 20];
    let mut left = bytes.saturating_sub(head.len());
    while left > 0 {
        let n = left.min(zeros.len());
        stream.write_all(&zeros[..n]).map_err(fail)?;
        left -= n;
    }
    let mut line = String::new();
    BufReader::new(stream).read_line(&mut line).map_err(fail)?;
    line.split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| LoadError(format!("upload {name}: bad status line {line:?}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_are_nearest_rank() {
        let mut values: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        assert_eq!(percentile(&mut values, 50.0), 50.0);
        assert_eq!(percentile(&mut values, 99.0), 99.0);
        assert_eq!(percentile(&mut values, 100.0), 100.0);
        assert_eq!(percentile(&mut [7.0], 99.0), 7.0);
        assert!(percentile(&mut [], 50.0).is_nan());
    }
}
