//! `matseg serve`: the local web app. Five pages: *segment* opens a photo
//! (bundled, uploaded, or from the folders the server was given) and a
//! click shows where else in it the material under the point is (more
//! clicks add to the selection, alt- or right-clicks leave a material
//! out, each drawn live), or splits it automatically; *browse*
//! pages through a generated dataset; *annotate* builds a point benchmark;
//! *evaluate* scores the model and baselines on one; *video* follows
//! clicked materials through a video. Each photo is
//! described once by the model; clicks are answered from the cached
//! descriptors.
//!
//! Safety: the server binds 127.0.0.1 unless told otherwise; it answers
//! only requests made by its own pages, with the token it makes each run
//! ([`guard`]); it serves only its own files and the folders it was given;
//! uploads go to disk within a bound; and when it is stopped (SIGINT,
//! SIGTERM) it stops its jobs and removes its temporary folder
//! (docs/serve.md).

#![warn(missing_docs)]

pub mod annotate;
pub mod app;
pub mod browse;
pub mod described;
pub mod evaluate;
pub mod guard;
pub mod jobs;
pub mod load;
pub mod model;
pub mod photos;
pub mod roots;
pub mod select;
pub mod uploads;
pub mod video;

use annotate::BenchFolder;
use app::AppState;
use browse::DatasetFolder;
use described::DescribedCache;
pub use guard::TokenChoice;
use guard::{new_token, Access};
use matseg_image::MemoryBudget;
use matseg_pipeline::segment::load_model;
use roots::Roots;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use uploads::UploadFolder;

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// Another host than the loopback without a token.
    #[error("--host {0}: serving beyond this machine needs a token (leave out --no-token)")]
    NoToken(String),
    /// A chosen token that cannot be used (too short, or not URL-safe).
    #[error(transparent)]
    Token(#[from] guard::TokenError),
    /// The server's temporary folder or token could not be made.
    #[error("cannot start: {0}")]
    Setup(String),
    /// A folder that cannot be served.
    #[error("{}: {message}", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A served folder could not be listed.
    #[error(transparent)]
    Listing(#[from] matseg_image::LibraryError),
    /// The model could not be loaded.
    #[error(transparent)]
    Model(#[from] matseg_pipeline::error::PipelineError),
    /// The address could not be bound or served.
    #[error("{address}: {message}")]
    Bind {
        /// The address.
        address: String,
        /// What went wrong.
        message: String,
    },
}

/// What `matseg serve` was asked for.
#[derive(Clone, Debug)]
pub struct ServeOptions {
    /// The model: `default`, a run folder or a weights file.
    pub model: PathBuf,
    /// Folders of photos besides the bundled ones, or of datasets to
    /// browse.
    pub data: Vec<PathBuf>,
    /// Point benchmark folders to annotate and evaluate.
    pub bench: Vec<PathBuf>,
    /// The address to bind.
    pub host: String,
    /// Other names the server answers to (the `Host` of a request),
    /// besides the loopback names and `host`.
    pub allowed_hosts: Vec<String>,
    /// The port (0: any free one).
    pub port: u16,
    /// The token API calls must carry.
    pub token: TokenChoice,
    /// Bound on the described photos kept, in MiB.
    pub cache_mb: usize,
    /// Bound on the uploads on disk, arriving and kept, in MiB.
    pub upload_mb: usize,
    /// The device the model runs on.
    pub device: matseg_image::device::ComputeDevice,
}

impl ServeOptions {
    /// The address bound unless told otherwise: this machine only.
    pub const HOST: &'static str = "127.0.0.1";
    /// The port bound unless told otherwise.
    pub const PORT: u16 = 8080;
    /// The bound on described photos kept unless told otherwise, in MiB.
    pub const CACHE_MB: usize = 1024;
    /// The bound on uploads on disk unless told otherwise, in MiB.
    pub const UPLOAD_MB: usize = 2048;
}

impl Default for ServeOptions {
    /// `matseg serve` with no arguments: the shipped model on the CPU, the
    /// bundled photos only, on [`Self::HOST`]:[`Self::PORT`], a token per
    /// run.
    fn default() -> Self {
        Self {
            model: "default".into(),
            data: Vec::new(),
            bench: Vec::new(),
            host: Self::HOST.into(),
            allowed_hosts: Vec::new(),
            port: Self::PORT,
            token: TokenChoice::PerRun,
            cache_mb: Self::CACHE_MB,
            upload_mb: Self::UPLOAD_MB,
            device: matseg_image::device::ComputeDevice::Cpu,
        }
    }
}

/// Whether `host` is this machine only.
fn is_loopback(host: &str) -> bool {
    matches!(host, "127.0.0.1" | "localhost" | "::1" | "[::1]")
}

/// The app's state: the model loaded, the folders checked.
pub fn state(options: &ServeOptions) -> Result<Arc<AppState>, ServeError> {
    let token = match &options.token {
        TokenChoice::Off if !is_loopback(&options.host) => {
            return Err(ServeError::NoToken(options.host.clone()))
        }
        TokenChoice::Off => None,
        TokenChoice::Given(token) => {
            guard::check_token(token).map_err(ServeError::Token)?;
            Some(token.clone())
        }
        TokenChoice::PerRun => {
            Some(new_token().map_err(|e| ServeError::Setup(format!("no random token: {e}")))?)
        }
    };
    let mut roots = Roots::default();
    let add = |roots: &mut Roots, name: &str, dir: &PathBuf| {
        if !dir.is_dir() {
            return Err(ServeError::Folder {
                path: dir.clone(),
                message: "no such folder".into(),
            });
        }
        roots.add(name, dir).map_err(|e| ServeError::Folder {
            path: dir.clone(),
            message: e.to_string(),
        })
    };
    let bundled = matseg_pipeline::sources::assets_dir().join("photos");
    add(&mut roots, "photos", &bundled)?;
    let mut photo_roots = vec!["photos".to_string()];
    let mut datasets = Vec::new();
    // Folders are kept by their canonical path: the one form the API
    // hands out and takes back, however they were named.
    for (i, dir) in options.data.iter().enumerate() {
        let name = format!("data{i}");
        let dir = add(&mut roots, &name, dir)?;
        match DatasetFolder::open(&name, dir) {
            Some(dataset) => datasets.push(dataset),
            None => photo_roots.push(name),
        }
    }
    let mut benches = Vec::new();
    for (i, dir) in options.bench.iter().enumerate() {
        let name = format!("bench{i}");
        let given = dir;
        let dir = add(&mut roots, &name, given)?;
        if !dir.join("images").is_dir() {
            return Err(ServeError::Folder {
                path: given.clone(),
                message: "a benchmark folder needs an images/ folder of photos".into(),
            });
        }
        photo_roots.push(name.clone());
        benches.push(BenchFolder::new(&name, dir));
    }
    let photo_root = |name: &&str| photo_roots.iter().any(|p| p == name);
    let served = || roots.iter().filter(|(name, _)| photo_root(name));
    let photos = roots::files_under(served(), &photos::PHOTO_EXTENSIONS)?;
    let videos = roots::files_under(served(), &video::VIDEO_EXTENSIONS)?;
    let model = load_model(&options.model, options.device)?;
    let folder = tempfile::Builder::new()
        .prefix("matseg-serve-")
        .tempdir()
        .map_err(|e| ServeError::Folder {
            path: std::env::temp_dir(),
            message: format!("cannot make the server's temporary folder: {e}"),
        })?;
    let upload_limit = (options.upload_mb as u64).saturating_mul(1 << 20);
    let uploads = UploadFolder::new(folder.path().join("uploads"), upload_limit)
        .map_err(|e| ServeError::Setup(format!("{}: {e}", folder.path().display())))?;
    let videos = video::Videos::new(videos, folder.path().join("tracks"));
    let budget = MemoryBudget::new(options.cache_mb.saturating_mul(1 << 20));
    Ok(Arc::new(AppState {
        model: model::ServedModel::new(model),
        device: options.device,
        roots,
        photos,
        described: DescribedCache::new(budget.clone()),
        photo_work: Default::default(),
        budget,
        folder,
        uploads,
        datasets,
        benches,
        evaluations: Default::default(),
        videos,
        workers: Default::default(),
        access: Arc::new(Access::new(&options.host, &options.allowed_hosts, token)),
    }))
}

/// Where a started server is.
#[derive(Clone, Debug)]
pub struct Ready {
    /// The address bound (the port chosen when it was 0).
    pub address: SocketAddr,
    /// The address to open, with the token: `http://ADDRESS/?token=T`.
    pub url: String,
    /// The token API calls carry, when there is one.
    pub token: Option<String>,
}

/// How long a stopping server waits for the requests under way.
const REQUESTS_GRACE: Duration = Duration::from_secs(5);

/// How long a stopping server waits for its jobs to stop.
const JOBS_GRACE: Duration = Duration::from_secs(20);

/// Serves the app until the process gets SIGINT (Ctrl-C) or SIGTERM;
/// `on_ready` gets where it listens. Then it answers the requests under
/// way, stops its jobs and removes its temporary folder before returning;
/// a second signal ends the process at once (the folder removed first).
pub fn serve(options: &ServeOptions, on_ready: impl FnOnce(&Ready)) -> Result<(), ServeError> {
    serve_until(options, on_ready, |state| async move {
        let Ok(mut signals) = stop_signals() else {
            // No signal can be watched: the server runs until killed.
            return std::future::pending().await;
        };
        signals.recv().await;
        tokio::spawn(async move {
            if signals.recv().await.is_some() {
                let _ = std::fs::remove_dir_all(state.folder.path());
                std::process::exit(130);
            }
        });
    })
}

/// Serves the app until the future `stop` makes (from the app's state)
/// completes; `on_ready` gets where it listens. Then, as [`serve`] does, it
/// stops the jobs, lets the requests under way finish (for up to a few
/// seconds) and removes the server's temporary folder before returning.
pub fn serve_until<F>(
    options: &ServeOptions,
    on_ready: impl FnOnce(&Ready),
    stop: impl FnOnce(Arc<AppState>) -> F,
) -> Result<(), ServeError>
where
    F: std::future::Future<Output = ()> + Send + 'static,
{
    described::map_large_allocations();
    let state = state(options)?;
    let address = format!("{}:{}", options.host, options.port);
    let bind_error = |message: String| ServeError::Bind {
        address: address.clone(),
        message,
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_io()
        .enable_time()
        .build()
        .map_err(|e| bind_error(e.to_string()))?;
    let served = runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind(&address)
            .await
            .map_err(|e| bind_error(e.to_string()))?;
        let local = listener
            .local_addr()
            .map_err(|e| bind_error(e.to_string()))?;
        let token = state.access.token.clone();
        let query = token
            .as_ref()
            .map(|t| format!("?token={t}"))
            .unwrap_or_default();
        on_ready(&Ready {
            address: local,
            url: format!("http://{local}/{query}"),
            token,
        });
        let stopping = watch_stop(stop(state.clone()), state.clone());
        let asked = |mut stopping: tokio::sync::watch::Receiver<bool>| async move {
            let _ = stopping.wait_for(|&stop| stop).await;
        };
        let server = axum::serve(listener, app::router(state.clone()))
            .with_graceful_shutdown(asked(stopping.clone()));
        // Once stopping, requests under way are waited for a while.
        let grace = async {
            asked(stopping).await;
            tokio::time::sleep(REQUESTS_GRACE).await;
        };
        tokio::select! {
            served = async { server.await } => served.map_err(|e| bind_error(e.to_string())),
            () = grace => Ok(()),
        }
    });
    runtime.shutdown_timeout(Duration::from_secs(1));
    state.workers.stop_all(JOBS_GRACE);
    let _ = std::fs::remove_dir_all(state.folder.path());
    served
}

/// Waits for `stop` on behalf of the server in `state`: then its jobs are
/// told to stop and the answer turns true.
fn watch_stop(
    stop: impl std::future::Future<Output = ()> + Send + 'static,
    state: Arc<AppState>,
) -> tokio::sync::watch::Receiver<bool> {
    let (send, receive) = tokio::sync::watch::channel(false);
    tokio::spawn(async move {
        stop.await;
        state.workers.cancel_all();
        let _ = send.send(true);
    });
    receive
}

/// A channel that gets one message for each SIGINT or SIGTERM the process
/// receives.
fn stop_signals() -> std::io::Result<tokio::sync::mpsc::Receiver<()>> {
    use tokio::signal::unix::{signal, SignalKind};
    let (send, receive) = tokio::sync::mpsc::channel(4);
    for kind in [SignalKind::interrupt(), SignalKind::terminate()] {
        let mut signals = signal(kind)?;
        let send = send.clone();
        tokio::spawn(async move {
            while signals.recv().await.is_some() {
                if send.send(()).await.is_err() {
                    break;
                }
            }
        });
    }
    Ok(receive)
}
