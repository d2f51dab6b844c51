//! The frames of a video, one at a time (pipeline.md §8.2): a folder of
//! PNG or JPEG frames in name order, or a video file (MP4/H.264, WebM/VP9,
//! MKV, anything FFmpeg reads) decoded by the `ffmpeg` program into raw RGB
//! through a pipe, so memory holds one frame whatever the video's length.

use crate::error::PipelineError;
use image::RgbImage;
use matseg_image::io::{has_image_extension, read_dimensions, read_rgb};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};

/// The longest frame side followed (8K); larger frames are refused.
pub const MAX_FRAME_SIDE: u32 = 8192;

/// Where frames come from.
#[derive(Clone, Debug)]
pub struct FrameSource {
    /// The folder or video file, as named in errors.
    pub path: PathBuf,
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// Frames per second (a folder: 25, FFmpeg's default for image sequences).
    pub fps: f64,
    kind: SourceKind,
}

#[derive(Clone, Debug)]
enum SourceKind {
    /// Image files, in name order.
    Folder(Vec<PathBuf>),
    /// A video, the ffmpeg program that decodes it, and its frame count
    /// (its video packets, as the container lists them).
    Video { ffmpeg: PathBuf, frames: u64 },
}

/// The ffmpeg (or ffprobe) program: `$MATSEG_FFMPEG` (and the ffprobe
/// beside it), else the one `scripts/ffmpeg-env.sh` installs into the
/// checkout this was built from, else `program` on the PATH.
pub fn ffmpeg_program(program: &str) -> PathBuf {
    if let Some(ffmpeg) = std::env::var_os("MATSEG_FFMPEG") {
        let ffmpeg = PathBuf::from(ffmpeg);
        return match program {
            "ffmpeg" => ffmpeg,
            _ => ffmpeg.with_file_name(program),
        };
    }
    let installed = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../.venv/ffmpeg")
        .join(program);
    if installed.is_file() {
        installed
    } else {
        PathBuf::from(program)
    }
}

/// Whether the ffmpeg program can be run.
pub fn ffmpeg_available() -> bool {
    Command::new(ffmpeg_program("ffmpeg"))
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

impl FrameSource {
    /// Opens `path`: a folder of frames, or a video file. Errors name the
    /// file: no frames, an unreadable or corrupt file, a frame over
    /// [`MAX_FRAME_SIDE`], a folder whose frames differ in size.
    pub fn open(path: &Path) -> Result<Self, PipelineError> {
        if path.is_dir() {
            Self::open_folder(path)
        } else if path.is_file() {
            Self::open_video(path)
        } else {
            Err(PipelineError::file(
                path.display(),
                "no such file or folder",
            ))
        }
    }

    fn open_folder(dir: &Path) -> Result<Self, PipelineError> {
        let listing = std::fs::read_dir(dir)
            .map_err(|e| PipelineError::file(dir.display(), format!("cannot list: {e}")))?;
        let mut files: Vec<PathBuf> = listing
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file() && has_image_extension(p))
            .collect();
        files.sort();
        let first = files.first().ok_or_else(|| {
            PipelineError::file(dir.display(), "no frames (PNG or JPEG files) in the folder")
        })?;
        let (width, height) = read_dimensions(first)?;
        check_side(first, width, height)?;
        for file in &files[1..] {
            let size = read_dimensions(file)?;
            if size != (width, height) {
                return Err(different_size(file, size, (width, height)));
            }
        }
        Ok(FrameSource {
            path: dir.to_path_buf(),
            width,
            height,
            fps: 25.0,
            kind: SourceKind::Folder(files),
        })
    }

    fn open_video(file: &Path) -> Result<Self, PipelineError> {
        let ffprobe = ffmpeg_program("ffprobe");
        let output = Command::new(&ffprobe)
            .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
            .arg("stream=width,height,avg_frame_rate,nb_read_packets:stream_side_data=rotation")
            .args(["-count_packets", "-of", "json"])
            .arg(file)
            .output()
            .map_err(|e| {
                PipelineError::file(
                    file.display(),
                    format!(
                        "cannot run {} to read the video ({e}); scripts/ffmpeg-env.sh installs it, or pass a folder of frames",
                        ffprobe.display()
                    ),
                )
            })?;
        if !output.status.success() {
            return Err(PipelineError::file(
                file.display(),
                format!("not a readable video: {}", last_line(&output.stderr, file)),
            ));
        }
        let probe: serde_json::Value = serde_json::from_slice(&output.stdout)
            .map_err(|e| PipelineError::file(file.display(), format!("ffprobe's answer: {e}")))?;
        let stream = &probe["streams"][0];
        let (Some(w), Some(h)) = (stream["width"].as_u64(), stream["height"].as_u64()) else {
            return Err(PipelineError::file(
                file.display(),
                "not a video: no video stream",
            ));
        };
        // FFmpeg turns frames upright by the stream's rotation.
        let rotation = stream["side_data_list"][0]["rotation"]
            .as_i64()
            .unwrap_or(0);
        // Sides past u32 are as out of range as any over the limit.
        let (w, h) = (
            u32::try_from(w).unwrap_or(u32::MAX),
            u32::try_from(h).unwrap_or(u32::MAX),
        );
        let (width, height) = if rotation.rem_euclid(180) == 90 {
            (h, w)
        } else {
            (w, h)
        };
        check_side(file, width, height)?;
        let fps = stream["avg_frame_rate"]
            .as_str()
            .and_then(parse_rate)
            .unwrap_or(25.0);
        let frames = stream["nb_read_packets"]
            .as_str()
            .and_then(|n| n.parse().ok())
            .unwrap_or(0);
        if frames == 0 {
            return Err(PipelineError::file(
                file.display(),
                "not a video: its video stream has no frames",
            ));
        }
        Ok(FrameSource {
            path: file.to_path_buf(),
            width,
            height,
            fps,
            kind: SourceKind::Video {
                ffmpeg: ffmpeg_program("ffmpeg"),
                frames,
            },
        })
    }

    /// The number of frames (one at least): the folder's files, or the
    /// video's frames as its container counts them (a corrupt video may
    /// decode fewer).
    pub fn frame_count(&self) -> u64 {
        match &self.kind {
            SourceKind::Folder(files) => files.len() as u64,
            SourceKind::Video { frames, .. } => *frames,
        }
    }

    /// Frame `n` (from 0), the frames before it decoded and dropped; past
    /// the end, an error that says how many frames there are.
    pub fn frame(&self, n: u64) -> Result<RgbImage, PipelineError> {
        match self.frames()?.nth(n as usize) {
            Some(frame) => frame,
            None => {
                let frames = self.frames()?.try_fold(0u64, |k, f| f.map(|_| k + 1))?;
                Err(PipelineError::setting(
                    "frame",
                    Some(n),
                    format!("past the end: {} has {frames} frames", self.path.display()),
                ))
            }
        }
    }

    /// The frames from the first, one at a time.
    pub fn frames(&self) -> Result<Frames, PipelineError> {
        let inner = match &self.kind {
            SourceKind::Folder(files) => FramesInner::Folder(files.clone().into_iter()),
            SourceKind::Video { ffmpeg, .. } => {
                let mut child = Command::new(ffmpeg)
                    .args(["-v", "error", "-xerror", "-nostdin", "-i"])
                    .arg(&self.path)
                    .args(["-map", "0:v:0", "-f", "rawvideo", "-pix_fmt", "rgb24"])
                    .arg("-vf")
                    .arg(format!("scale={}:{}", self.width, self.height))
                    .arg("-")
                    .stdout(Stdio::piped())
                    .stderr(Stdio::piped())
                    .spawn()
                    .map_err(|e| {
                        PipelineError::file(
                            self.path.display(),
                            format!("cannot run {}: {e}", ffmpeg.display()),
                        )
                    })?;
                let stdout = child.stdout.take().expect("piped");
                FramesInner::Video { child, stdout }
            }
        };
        Ok(Frames {
            path: self.path.clone(),
            width: self.width,
            height: self.height,
            next: 0,
            inner,
        })
    }
}

/// Frames in order; each item is a frame or why it could not be read.
pub struct Frames {
    path: PathBuf,
    width: u32,
    height: u32,
    next: u64,
    inner: FramesInner,
}

enum FramesInner {
    Folder(std::vec::IntoIter<PathBuf>),
    Video { child: Child, stdout: ChildStdout },
    Done,
}

impl Iterator for Frames {
    type Item = Result<RgbImage, PipelineError>;

    fn next(&mut self) -> Option<Self::Item> {
        let item = match &mut self.inner {
            FramesInner::Done => return None,
            FramesInner::Folder(files) => {
                let file = files.next()?;
                read_rgb(&file).map_err(PipelineError::from).and_then(|f| {
                    if f.dimensions() == (self.width, self.height) {
                        Ok(f)
                    } else {
                        Err(different_size(
                            &file,
                            f.dimensions(),
                            (self.width, self.height),
                        ))
                    }
                })
            }
            FramesInner::Video { child, stdout } => {
                let bytes = self.width as usize * self.height as usize * 3;
                let mut frame = vec![0u8; bytes];
                match read_full(stdout, &mut frame) {
                    Ok(n) if n == bytes => Ok(RgbImage::from_raw(self.width, self.height, frame)
                        .expect("width * height * 3 bytes")),
                    Ok(n) => {
                        let status = child.wait();
                        let mut stderr = Vec::new();
                        if let Some(mut e) = child.stderr.take() {
                            let _ = e.read_to_end(&mut stderr);
                        }
                        let failed = !status.is_ok_and(|s| s.success());
                        if n == 0 && !failed && self.next > 0 {
                            self.inner = FramesInner::Done;
                            return None;
                        }
                        let why = if failed || n > 0 {
                            format!(
                                "corrupt or truncated video after {} frames: {}",
                                self.next,
                                last_line(&stderr, &self.path)
                            )
                        } else {
                            "no frames in the video".to_string()
                        };
                        Err(PipelineError::file(self.path.display(), why))
                    }
                    Err(e) => Err(PipelineError::file(
                        self.path.display(),
                        format!("reading frames from ffmpeg: {e}"),
                    )),
                }
            }
        };
        if item.is_err() {
            self.stop();
        } else {
            self.next += 1;
        }
        Some(item)
    }
}

impl Frames {
    /// Stops decoding (the decoder process is ended).
    fn stop(&mut self) {
        if let FramesInner::Video { child, .. } = &mut self.inner {
            let _ = child.kill();
            let _ = child.wait();
        }
        self.inner = FramesInner::Done;
    }
}

impl Drop for Frames {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Reads until `buf` is full or the stream ends: the bytes read.
fn read_full(stream: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match stream.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

/// A frame rate such as `30000/1001` or `25/1`, when positive.
fn parse_rate(rate: &str) -> Option<f64> {
    let (n, d) = rate.split_once('/').unwrap_or((rate, "1"));
    let (n, d): (f64, f64) = (n.parse().ok()?, d.parse().ok()?);
    let fps = n / d;
    (n > 0.0 && d > 0.0 && fps.is_finite() && fps > 0.0).then_some(fps)
}

/// The last non-empty line FFmpeg wrote to stderr about `file`, without
/// the file's name it starts with (the error names it already).
fn last_line(stderr: &[u8], file: &Path) -> String {
    let text = String::from_utf8_lossy(stderr);
    let line = text
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("no message")
        .trim();
    let prefix = format!("{}: ", file.display());
    line.strip_prefix(&prefix).unwrap_or(line).to_string()
}

fn check_side(file: &Path, width: u32, height: u32) -> Result<(), PipelineError> {
    if width == 0 || height == 0 || width.max(height) > MAX_FRAME_SIDE {
        return Err(PipelineError::file(
            file.display(),
            format!(
                "frames are {width}x{height}; frames up to {MAX_FRAME_SIDE} px a side are followed"
            ),
        ));
    }
    Ok(())
}

fn different_size(file: &Path, (w, h): (u32, u32), (w0, h0): (u32, u32)) -> PipelineError {
    PipelineError::file(
        file.display(),
        format!("frame is {w}x{h}, the first frame {w0}x{h0}: all frames must have one size"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use matseg_image::io::encode_png_rgb;

    fn write_frame(dir: &Path, name: &str, w: u32, h: u32, v: u8) {
        let img = RgbImage::from_pixel(w, h, image::Rgb([v, 0, 0]));
        std::fs::write(dir.join(name), encode_png_rgb(&img)).unwrap();
    }

    #[test]
    fn a_folder_gives_its_frames_in_name_order() {
        let dir = tempfile::tempdir().unwrap();
        for (name, v) in [("f10.png", 3), ("f02.png", 2), ("f01.png", 1)] {
            write_frame(dir.path(), name, 4, 3, v);
        }
        std::fs::write(dir.path().join("notes.txt"), "x").unwrap();
        let source = FrameSource::open(dir.path()).unwrap();
        assert_eq!((source.width, source.height), (4, 3));
        let reds: Vec<u8> = source
            .frames()
            .unwrap()
            .map(|f| f.unwrap().get_pixel(0, 0).0[0])
            .collect();
        assert_eq!(reds, [1, 2, 3]);
    }

    #[test]
    fn bad_folders_are_refused_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let empty = FrameSource::open(dir.path()).unwrap_err().to_string();
        assert!(
            empty.ends_with("no frames (PNG or JPEG files) in the folder"),
            "{empty}"
        );
        write_frame(dir.path(), "a.png", 4, 3, 0);
        write_frame(dir.path(), "b.png", 5, 3, 0);
        let sizes = FrameSource::open(dir.path()).unwrap_err().to_string();
        assert!(
            sizes.contains("b.png: frame is 5x3, the first frame 4x3"),
            "{sizes}"
        );
        let missing = FrameSource::open(&dir.path().join("nope.mp4"))
            .unwrap_err()
            .to_string();
        assert!(
            missing.ends_with("nope.mp4: no such file or folder"),
            "{missing}"
        );
        assert!(check_side(Path::new("big.png"), 16384, 8640).is_err());
        assert_eq!(
            parse_rate("30000/1001").map(|r| (r * 100.0).round()),
            Some(2997.0)
        );
        assert_eq!(parse_rate("0/0"), None);
    }
}
