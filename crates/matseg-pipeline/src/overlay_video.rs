//! The overlay of a tracked video, written frame by frame: an H.264 MP4
//! through the `ffmpeg` program where it runs, else an animated PNG
//! preview (at most [`PREVIEW_SIDE`] px a side and [`PREVIEW_FRAMES`]
//! frames, every k-th frame of a longer video) that any browser plays.

use crate::error::PipelineError;
use crate::frames::{ffmpeg_available, ffmpeg_program};
use image::RgbImage;
use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};

/// The longest side of an animated PNG preview.
pub const PREVIEW_SIDE: u32 = 480;
/// The most frames of an animated PNG preview.
pub const PREVIEW_FRAMES: u64 = 300;

/// Where the overlay frames go.
pub enum OverlayVideo {
    /// Raw frames piped into an ffmpeg encoding an MP4.
    Mp4 {
        /// The encoder.
        child: Child,
        /// Its input.
        stdin: Option<ChildStdin>,
        /// The file it writes.
        path: PathBuf,
    },
    /// An animated PNG, every `every`-th frame.
    Apng {
        /// The PNG stream.
        writer: Box<png::Writer<BufWriter<File>>>,
        /// The file.
        path: PathBuf,
        /// Frames offered so far.
        offered: u64,
        /// One frame kept out of this many.
        every: u64,
        /// The preview's size.
        size: (u32, u32),
    },
}

impl OverlayVideo {
    /// An overlay of `frames` frames of `width x height` at `fps` in
    /// folder `dir`: `overlay.mp4` when ffmpeg runs (`prefer_mp4`), else
    /// `overlay.png`.
    pub fn create(
        dir: &Path,
        (width, height): (u32, u32),
        fps: f64,
        frames: u64,
        prefer_mp4: bool,
    ) -> Result<Self, PipelineError> {
        if prefer_mp4 && ffmpeg_available() {
            return Self::mp4(&dir.join("overlay.mp4"), (width, height), fps);
        }
        Self::apng(&dir.join("overlay.png"), (width, height), fps, frames)
    }

    fn mp4(path: &Path, (width, height): (u32, u32), fps: f64) -> Result<Self, PipelineError> {
        let ffmpeg = ffmpeg_program("ffmpeg");
        let mut child = Command::new(&ffmpeg)
            .args([
                "-y", "-v", "error", "-nostdin", "-f", "rawvideo", "-pix_fmt", "rgb24",
            ])
            .arg("-s")
            .arg(format!("{width}x{height}"))
            .arg("-r")
            .arg(format!("{fps}"))
            .args(["-i", "-", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2"])
            .args(["-c:v", "libx264", "-preset", "veryfast", "-crf", "23"])
            .args(["-pix_fmt", "yuv420p", "-movflags", "+faststart"])
            .arg(path)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                PipelineError::file(
                    path.display(),
                    format!("cannot run {}: {e}", ffmpeg.display()),
                )
            })?;
        let stdin = child.stdin.take();
        Ok(OverlayVideo::Mp4 {
            child,
            stdin,
            path: path.to_path_buf(),
        })
    }

    fn apng(
        path: &Path,
        (width, height): (u32, u32),
        fps: f64,
        frames: u64,
    ) -> Result<Self, PipelineError> {
        let every = frames.div_ceil(PREVIEW_FRAMES).max(1);
        let kept = frames.div_ceil(every).max(1);
        let scale = (PREVIEW_SIDE as f64 / width.max(height) as f64).min(1.0);
        let size = (
            ((width as f64 * scale).round() as u32).max(1),
            ((height as f64 * scale).round() as u32).max(1),
        );
        let fail = |e: &dyn std::fmt::Display| {
            PipelineError::file(path.display(), format!("cannot write: {e}"))
        };
        let file = File::create(path).map_err(|e| fail(&e))?;
        let mut encoder = png::Encoder::new(BufWriter::new(file), size.0, size.1);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::Fast);
        encoder.set_animated(kept as u32, 0).map_err(|e| fail(&e))?;
        // The preview's frame lasts `every` source frames, in 1/1000 s.
        let delay = ((every as f64 / fps.max(1e-3)) * 1000.0)
            .round()
            .clamp(1.0, 65535.0);
        encoder
            .set_frame_delay(delay as u16, 1000)
            .map_err(|e| fail(&e))?;
        let writer = encoder.write_header().map_err(|e| fail(&e))?;
        Ok(OverlayVideo::Apng {
            writer: Box::new(writer),
            path: path.to_path_buf(),
            offered: 0,
            every,
            size,
        })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        match self {
            OverlayVideo::Mp4 { path, .. } | OverlayVideo::Apng { path, .. } => path,
        }
    }

    /// Adds the next frame.
    pub fn push(&mut self, frame: &RgbImage) -> Result<(), PipelineError> {
        match self {
            OverlayVideo::Mp4 {
                stdin, path, child, ..
            } => {
                let pipe = stdin.as_mut().expect("open until finished");
                if let Err(e) = pipe.write_all(frame.as_raw()) {
                    let _ = child.kill();
                    return Err(PipelineError::file(
                        path.display(),
                        format!("the encoder stopped: {e}"),
                    ));
                }
                Ok(())
            }
            OverlayVideo::Apng {
                writer,
                path,
                offered,
                every,
                size,
            } => {
                let keep = *offered % *every == 0;
                *offered += 1;
                if !keep {
                    return Ok(());
                }
                let small = if frame.dimensions() == *size {
                    frame.clone()
                } else {
                    image::imageops::resize(
                        frame,
                        size.0,
                        size.1,
                        image::imageops::FilterType::Triangle,
                    )
                };
                writer
                    .write_image_data(small.as_raw())
                    .map_err(|e| PipelineError::file(path.display(), format!("cannot write: {e}")))
            }
        }
    }

    /// Closes the file: the encoder's end awaited, or the PNG's last chunk
    /// written.
    pub fn finish(self) -> Result<PathBuf, PipelineError> {
        match self {
            OverlayVideo::Mp4 {
                mut child,
                stdin,
                path,
            } => {
                drop(stdin);
                let mut stderr = String::new();
                if let Some(mut e) = child.stderr.take() {
                    let _ = e.read_to_string(&mut stderr);
                }
                let status = child.wait().map_err(|e| {
                    PipelineError::file(path.display(), format!("the encoder: {e}"))
                })?;
                if !status.success() {
                    let why = stderr
                        .lines()
                        .last()
                        .unwrap_or("no message")
                        .trim()
                        .to_string();
                    return Err(PipelineError::file(
                        path.display(),
                        format!("the encoder failed: {why}"),
                    ));
                }
                Ok(path)
            }
            OverlayVideo::Apng { writer, path, .. } => {
                (*writer).finish().map_err(|e| {
                    PipelineError::file(path.display(), format!("cannot write: {e}"))
                })?;
                Ok(path)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_animated_preview_keeps_every_kth_frame_at_the_preview_size() {
        let dir = tempfile::tempdir().unwrap();
        let frames = 2 * PREVIEW_FRAMES + 1;
        let mut video = OverlayVideo::create(dir.path(), (960, 20), 30.0, frames, false).unwrap();
        for i in 0..frames {
            video
                .push(&RgbImage::from_pixel(960, 20, image::Rgb([i as u8, 0, 0])))
                .unwrap();
        }
        let path = video.finish().unwrap();
        let decoder = png::Decoder::new(std::io::BufReader::new(File::open(&path).unwrap()));
        let reader = decoder.read_info().unwrap();
        let info = reader.info();
        assert_eq!((info.width, info.height), (PREVIEW_SIDE, 10));
        let control = info.animation_control.unwrap();
        // 601 frames, one kept in 3: 201; each shown for 3 frames at 30 fps.
        assert_eq!(control.num_frames, 201);
        assert_eq!(info.frame_control.unwrap().delay_num, 100);
    }
}
