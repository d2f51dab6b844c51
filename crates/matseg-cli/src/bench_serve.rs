//! `matseg bench-serve`: the web app under load on loopback. Writes photos
//! of a chosen size, starts `matseg serve` on them as a child process,
//! optionally sends it concurrent video uploads while watching its memory,
//! describes each photo with a first click (the descriptor pass), then has
//! 1, 16... concurrent clients click random points on photos already
//! described for a bounded time, and reads the server's memory
//! (`matseg_serve::load`, `matseg_pipeline::bench::clock`). With
//! `--while-evaluating BENCH`, an evaluation of that point benchmark runs
//! in the server's background from the descriptor pass to the last round.
//! With `--describe-at-once`, it measures memory instead: the first click
//! on every photo sent at once, to a new server each run, and the server's
//! memory before and at its peak.

use anyhow::{bail, Context, Result};
use matseg_pipeline::bench::clock::process_memory_mib;
use matseg_serve::load::{
    clicks, first_clicks_at_once, percentile, video_uploads, write_photos, AtOnceStats, ClickStats,
    Connection, ServerAddress, UploadStats,
};
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// Arguments of `matseg bench-serve`.
#[derive(clap::Args)]
pub struct Args {
    /// Photos to describe (each once, by its first click).
    #[arg(long, default_value_t = 100)]
    photos: usize,
    /// Size of each photo, in megapixels.
    #[arg(long, default_value_t = 1.0)]
    megapixels: f64,
    /// Concurrent clients of each click round.
    #[arg(long, value_delimiter = ',', default_value = "1,16")]
    clients: Vec<usize>,
    /// Seconds each click round lasts.
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    /// Clicks go to this many of the photos described last (still cached).
    #[arg(long, default_value_t = 8)]
    warm: usize,
    /// The server's bound on described photos, in MiB.
    #[arg(long, default_value_t = 1024)]
    cache_mb: usize,
    /// The model the server runs.
    #[arg(long, default_value = "default")]
    model: String,
    /// The `matseg` program to start as the server (another build, to
    /// compare): this one unless told otherwise.
    #[arg(long, value_name = "PROGRAM")]
    server: Option<std::path::PathBuf>,
    /// A point benchmark folder: its evaluation (the served model and the
    /// baselines the evaluate page ticks) runs in the server's background
    /// during the descriptor pass and every click round.
    #[arg(long, value_name = "BENCH")]
    while_evaluating: Option<std::path::PathBuf>,
    /// Before the clicks: this many video uploads sent at once (each a
    /// small video padded to --upload-size-mb), the server's memory watched
    /// while they arrive (needs ffmpeg to make the video).
    #[arg(long, default_value_t = 0)]
    uploads: usize,
    /// The size of each upload, in MiB.
    #[arg(long, default_value_t = 500)]
    upload_size_mb: usize,
    /// Instead of the click rounds: the first click on every photo sent
    /// at once (the selection the segment page asks for), to a new server
    /// each run, and the server's memory (RSS) before and at its peak.
    #[arg(long)]
    describe_at_once: bool,
    /// Runs of --describe-at-once (the median is reported).
    #[arg(long, default_value_t = 1)]
    runs: usize,
    /// Print JSON instead of tables.
    #[arg(long)]
    json: bool,
}

/// The server as a child process; stopped when dropped.
struct Server {
    child: Child,
    address: ServerAddress,
}

impl Server {
    fn start(data: &std::path::Path, args: &Args) -> Result<Self> {
        let exe = match &args.server {
            Some(program) => program.clone(),
            None => std::env::current_exe().context("cannot find the matseg binary")?,
        };
        let mut child = Command::new(exe)
            .args(["serve", "--json", "--port", "0", "--model", &args.model])
            .arg("--cache-mb")
            .arg(args.cache_mb.to_string())
            .arg("--data")
            .arg(data)
            .args(
                args.while_evaluating
                    .iter()
                    .flat_map(|b| [std::ffi::OsStr::new("--bench"), b.as_os_str()]),
            )
            .stdout(Stdio::piped())
            .spawn()
            .context("cannot start matseg serve")?;
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("piped"))
            .read_line(&mut line)
            .context("matseg serve printed no address")?;
        let address = serde_json::from_str::<serde_json::Value>(&line)
            .ok()
            .and_then(|ready| {
                Some(ServerAddress {
                    host: ready["address"].as_str()?.to_string(),
                    token: ready["token"].as_str().map(str::to_string),
                })
            });
        match address {
            Some(address) => Ok(Self { child, address }),
            None => {
                let _ = child.kill();
                bail!("matseg serve did not start: {line:?}")
            }
        }
    }

    fn memory(&self) -> (f64, f64) {
        process_memory_mib(self.child.id()).unwrap_or((f64::NAN, f64::NAN))
    }
}

impl Drop for Server {
    /// Stops the server as Ctrl-C would (it removes its temporary folder),
    /// killing it only when it has not ended within a minute.
    fn drop(&mut self) {
        #[cfg(all(target_os = "linux", target_env = "gnu"))]
        {
            // SAFETY: a signal to the child process this command started.
            unsafe {
                libc::kill(self.child.id() as libc::pid_t, libc::SIGTERM);
            }
            let started = std::time::Instant::now();
            while started.elapsed() < Duration::from_secs(60) {
                if let Ok(Some(_)) = self.child.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs `matseg bench-serve`.
pub fn run(args: Args) -> Result<()> {
    if args.photos == 0 || args.warm == 0 || args.clients.contains(&0) || args.megapixels <= 0.0 {
        bail!("--photos, --warm, --clients and --megapixels must be positive");
    }
    let dir = tempfile::tempdir().context("cannot make a folder for the photos")?;
    let photos = write_photos(dir.path(), args.photos, args.megapixels)?;
    if args.describe_at_once {
        return describe_at_once(dir.path(), &photos, &args);
    }
    let server = Server::start(dir.path(), &args)?;
    let (_, idle_peak) = server.memory();
    let uploads = (args.uploads > 0)
        .then(|| {
            let head = small_video(dir.path())?;
            let rss = || server.memory().0;
            let bytes = args.upload_size_mb << 20;
            Ok::<_, anyhow::Error>(video_uploads(
                &server.address,
                &head,
                args.uploads,
                bytes,
                &rss,
            ))
        })
        .transpose()?;

    // The descriptor pass: each photo's first click.
    let mut connection = Connection::open(&server.address)?;
    let mut evaluated = Vec::new();
    if args.while_evaluating.is_some() {
        start_evaluation(&mut connection)?;
    }
    let mut describe_ms = Vec::new();
    for (name, w, h) in &photos {
        let answer = connection.get(&matseg_serve::load::click_path(name, w / 2, h / 2))?;
        if answer.status != 200 {
            bail!(
                "{name}: the first click failed with status {}",
                answer.status
            );
        }
        describe_ms.push(answer.server_ms);
    }
    if args.while_evaluating.is_some() {
        evaluated.push(evaluation_running(&mut connection)?);
    }
    let (described_rss, described_peak) = server.memory();
    let (_, status) = connection.get_body("/api/status")?;
    let status: serde_json::Value = serde_json::from_slice(&status)?;
    let cached_mib = status["described_mib"].as_f64().unwrap_or(f64::NAN);
    let megapixels =
        photos.iter().map(|(_, w, h)| (w * h) as f64).sum::<f64>() / photos.len() as f64 / 1e6;

    let warm = &photos[photos.len().saturating_sub(args.warm)..];
    let mut rounds: Vec<ClickStats> = Vec::new();
    for &clients in &args.clients {
        if args.while_evaluating.is_some() {
            start_evaluation(&mut connection)?;
        }
        let duration = Duration::from_secs_f64(args.seconds);
        rounds.push(clicks(&server.address, warm, clients, duration));
        if args.while_evaluating.is_some() {
            evaluated.push(evaluation_running(&mut connection)?);
        }
    }
    if args.while_evaluating.is_some() {
        connection.send("DELETE", "/api/evaluate?root=bench0")?;
    }
    let (final_rss, final_peak) = server.memory();
    let describe_p50 = percentile(&mut describe_ms, 50.0);
    let describe_p99 = percentile(&mut describe_ms, 99.0);

    if args.json {
        let out = serde_json::json!({
            "photos": args.photos, "megapixels": megapixels, "cache_mb": args.cache_mb,
            "described_mib": cached_mib,
            "describe_p50_ms": describe_p50, "describe_p99_ms": describe_p99,
            "rss_idle_peak_mib": idle_peak,
            "rss_after_photos_mib": described_rss, "rss_peak_after_photos_mib": described_peak,
            "rss_final_mib": final_rss, "rss_peak_mib": final_peak,
            "clicks": rounds,
            "evaluating_throughout": evaluated,
            "uploads": uploads,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    if let Some(u) = &uploads {
        print_uploads(u);
    }
    println!(
        "{} photos of {megapixels:.2} MP on average; descriptor pass (first click, server time): median {describe_p50:.0} ms, p99 {describe_p99:.0} ms",
        args.photos
    );
    println!(
        "server memory (RSS): {idle_peak:.0} MiB at start, {described_rss:.0} MiB after {} photos (peak {described_peak:.0}), {final_rss:.0} MiB at the end (peak {final_peak:.0}); described photos kept: {cached_mib:.0} MiB of the {} MiB bound",
        args.photos, args.cache_mb
    );
    if let Some(bench) = &args.while_evaluating {
        println!(
            "an evaluation of {} ran in the background throughout the descriptor pass, then each round: {evaluated:?}",
            bench.display()
        );
    }
    println!("| clients | clicks | errors | server p50 ms | server p99 ms | round trip p50 ms | round trip p99 ms | clicks/s |");
    println!("|---|---|---|---|---|---|---|---|");
    for r in &rounds {
        println!(
            "| {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            r.clients,
            r.requests,
            r.errors,
            r.server_p50_ms,
            r.server_p99_ms,
            r.round_trip_p50_ms,
            r.round_trip_p99_ms,
            r.per_second
        );
    }
    Ok(())
}

/// One run of `--describe-at-once`: the server's memory, MiB, and what
/// the clicks got.
struct AtOnceRun {
    /// RSS once started (the model loaded), before any click.
    rss_idle_mib: f64,
    /// The highest RSS until every click was answered (VmHWM).
    rss_peak_mib: f64,
    /// RSS after.
    rss_after_mib: f64,
    /// Described photos kept, as the server counts them.
    described_mib: f64,
    clicks: AtOnceStats,
}

impl AtOnceRun {
    /// The peak above the idle RSS, MiB.
    fn growth(&self) -> f64 {
        self.rss_peak_mib - self.rss_idle_mib
    }

    fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "rss_idle_mib": self.rss_idle_mib, "rss_peak_mib": self.rss_peak_mib,
            "rss_after_mib": self.rss_after_mib, "growth_mib": self.growth(),
            "described_mib": self.described_mib, "clicks": self.clicks,
        })
    }
}

/// `--describe-at-once`: each run, a new server and the first click on
/// every photo sent at once; the server's memory per run and the median
/// of its peak above its idle RSS, against the bound it should keep
/// within (`--cache-mb` plus 300 MiB).
fn describe_at_once(
    dir: &std::path::Path,
    photos: &[(String, u32, u32)],
    args: &Args,
) -> Result<()> {
    if args.runs == 0 {
        bail!("--runs must be positive");
    }
    let mut runs = Vec::new();
    for _ in 0..args.runs {
        let server = Server::start(dir, args)?;
        let (rss_idle_mib, _) = server.memory();
        let clicks = first_clicks_at_once(&server.address, photos);
        let (rss_after_mib, rss_peak_mib) = server.memory();
        let (_, status) = Connection::open(&server.address)?.get_body("/api/status")?;
        let status: serde_json::Value = serde_json::from_slice(&status)?;
        runs.push(AtOnceRun {
            rss_idle_mib,
            rss_peak_mib,
            rss_after_mib,
            described_mib: status["described_mib"].as_f64().unwrap_or(f64::NAN),
            clicks,
        });
    }
    let mut growth: Vec<f64> = runs.iter().map(AtOnceRun::growth).collect();
    let median = percentile(&mut growth, 50.0);
    let bound = args.cache_mb as f64 + 300.0;
    let megapixels =
        photos.iter().map(|(_, w, h)| (w * h) as f64).sum::<f64>() / photos.len() as f64 / 1e6;
    if args.json {
        let out = serde_json::json!({
            "photos": photos.len(), "megapixels": megapixels, "cache_mb": args.cache_mb,
            "runs": runs.iter().map(AtOnceRun::json).collect::<Vec<_>>(),
            "median_growth_mib": median, "bound_mib": bound,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!(
        "{} photos of {megapixels:.1} MP, first clicks all at once, --cache-mb {}: {} runs",
        photos.len(),
        args.cache_mb,
        runs.len()
    );
    println!("| run | idle RSS MiB | peak RSS MiB | peak - idle MiB | RSS after MiB | described MiB | statuses | seconds |");
    println!("|---|---|---|---|---|---|---|---|");
    for (i, r) in runs.iter().enumerate() {
        println!(
            "| {} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:?} | {:.1} |",
            i + 1,
            r.rss_idle_mib,
            r.rss_peak_mib,
            r.growth(),
            r.rss_after_mib,
            r.described_mib,
            r.clicks.statuses,
            r.clicks.seconds
        );
    }
    println!(
        "median peak above idle: {median:.0} MiB (the bound: --cache-mb + 300 = {bound:.0} MiB)"
    );
    Ok(())
}

/// The baselines the evaluate page ticks by default, beside the model.
const EVALUATED_BASELINES: &str = "rgb,lab,texture,position";

/// Starts the evaluation of the benchmark, unless one is running.
fn start_evaluation(connection: &mut Connection) -> Result<()> {
    if evaluation_running(connection)? {
        return Ok(());
    }
    let (answer, body) = connection.send(
        "POST",
        &format!("/api/evaluate?root=bench0&baselines={EVALUATED_BASELINES}"),
    )?;
    if answer.status != 200 {
        bail!(
            "the evaluation did not start: {}",
            String::from_utf8_lossy(&body)
        );
    }
    Ok(())
}

/// Whether the benchmark's evaluation is running.
fn evaluation_running(connection: &mut Connection) -> Result<bool> {
    let (_, body) = connection.get_body("/api/evaluate?root=bench0")?;
    let status: serde_json::Value = serde_json::from_slice(&body)?;
    Ok(status["state"] == "running")
}

/// A small H.264 MP4 (five 64 x 48 frames) made by ffmpeg in `dir`: the
/// head of each load upload.
fn small_video(dir: &std::path::Path) -> Result<Vec<u8>> {
    let file = dir.join("head.mp4");
    let ffmpeg = matseg_pipeline::frames::ffmpeg_program("ffmpeg");
    let made = Command::new(&ffmpeg)
        .args([
            "-v",
            "error",
            "-nostdin",
            "-y",
            "-f",
            "lavfi",
            "-i",
            "testsrc=size=64x48:rate=10",
        ])
        .args(["-frames:v", "5", "-c:v", "libx264", "-pix_fmt", "yuv420p"])
        .args(["-movflags", "+faststart"])
        .arg(&file)
        .status()
        .with_context(|| {
            format!(
                "--uploads: cannot run {} to make the video",
                ffmpeg.display()
            )
        })?;
    if !made.success() {
        bail!("--uploads: {} could not make the video", ffmpeg.display());
    }
    Ok(std::fs::read(&file)?)
}

/// The upload round's line.
fn print_uploads(u: &UploadStats) {
    let ok = u.statuses.iter().filter(|&&s| s == 200).count();
    println!(
        "{} uploads of {:.0} MiB at once ({ok} kept, statuses {:?}) in {:.1} s: server memory (RSS) {:.0} MiB before, peak {:.0} MiB while they arrived (+{:.0}), {:.0} MiB after",
        u.uploads,
        u.mib_each,
        u.statuses,
        u.seconds,
        u.rss_before_mib,
        u.rss_peak_mib,
        u.rss_peak_mib - u.rss_before_mib,
        u.rss_after_mib
    );
}
