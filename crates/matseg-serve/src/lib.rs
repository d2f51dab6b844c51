//! `matseg serve`: the local web app. Five pages: *segment* opens a photo
//! (bundled, uploaded, or from the folders the server was given) and a
//! click shows where else in it the material under the point is
//! (shift-clicks add points, whose segmentation is drawn live); *browse*
//! pages through a generated dataset; *annotate* builds a point benchmark;
//! *evaluate* scores the model and baselines on one; *video* follows
//! clicked materials through a video. Each photo is
//! described once by the model; clicks are answered from the cached
//! descriptors.
//!
//! Safety: the server binds 127.0.0.1 unless told otherwise, and any other
//! address needs a token that every API call must carry; it serves only
//! its own files and the folders it was given (docs/serve.md).

#![warn(missing_docs)]

pub mod annotate;
pub mod app;
pub mod browse;
pub mod described;
pub mod evaluate;
pub mod load;
pub mod photos;
pub mod roots;
pub mod video;

use annotate::BenchFolder;
use app::AppState;
use browse::DatasetFolder;
use described::{DescribedCache, Uploads};
use matseg_image::MemoryBudget;
use matseg_net::infer::NetModel;
use roots::Roots;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// Another host than the loopback without a token.
    #[error("--host {0}: serving beyond this machine needs --token")]
    NoToken(String),
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
    Model(#[from] matseg_net::NetError),
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
    /// The port (0: any free one).
    pub port: u16,
    /// The token API calls must carry.
    pub token: Option<String>,
    /// Bound on the described photos kept, in MiB.
    pub cache_mb: usize,
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
}

impl Default for ServeOptions {
    /// `matseg serve` with no arguments: the shipped model on the CPU, the
    /// bundled photos only, on [`Self::HOST`]:[`Self::PORT`], no token.
    fn default() -> Self {
        Self {
            model: "default".into(),
            data: Vec::new(),
            bench: Vec::new(),
            host: Self::HOST.into(),
            port: Self::PORT,
            token: None,
            cache_mb: Self::CACHE_MB,
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
    if !is_loopback(&options.host) && options.token.is_none() {
        return Err(ServeError::NoToken(options.host.clone()));
    }
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
    for (i, dir) in options.data.iter().enumerate() {
        let name = format!("data{i}");
        add(&mut roots, &name, dir)?;
        match DatasetFolder::open(&name, dir.clone()) {
            Some(dataset) => datasets.push(dataset),
            None => photo_roots.push(name),
        }
    }
    let mut benches = Vec::new();
    for (i, dir) in options.bench.iter().enumerate() {
        let name = format!("bench{i}");
        add(&mut roots, &name, dir)?;
        if !dir.join("images").is_dir() {
            return Err(ServeError::Folder {
                path: dir.clone(),
                message: "a benchmark folder needs an images/ folder of photos".into(),
            });
        }
        photo_roots.push(name.clone());
        benches.push(BenchFolder::new(&name, dir.clone()));
    }
    let photo_root = |name: &&str| photo_roots.iter().any(|p| p == name);
    let served = || roots.iter().filter(|(name, _)| photo_root(name));
    let photos = roots::files_under(served(), &photos::PHOTO_EXTENSIONS)?;
    let videos = roots::files_under(served(), &video::VIDEO_EXTENSIONS)?;
    let videos = video::Videos::new(videos).map_err(|e| ServeError::Folder {
        path: std::env::temp_dir(),
        message: format!("cannot make the server's temporary folder: {e}"),
    })?;
    let model = NetModel::load(&options.model, options.device)?;
    let budget = MemoryBudget::new(options.cache_mb.saturating_mul(1 << 20));
    Ok(Arc::new(AppState {
        model,
        device: options.device,
        roots,
        photos,
        described: DescribedCache::new(budget.clone()),
        uploads: Uploads::new(budget.clone()),
        budget,
        datasets,
        benches,
        evaluations: Default::default(),
        videos,
        token: options.token.clone(),
    }))
}

/// Serves the app until the process ends; `on_ready` gets the address
/// bound (the port chosen when `port` was 0).
pub fn serve(options: &ServeOptions, on_ready: impl FnOnce(SocketAddr)) -> Result<(), ServeError> {
    let state = state(options)?;
    let address = format!("{}:{}", options.host, options.port);
    let bind_error = |message: String| ServeError::Bind {
        address: address.clone(),
        message,
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_io()
        .build()
        .map_err(|e| bind_error(e.to_string()))?;
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind(&address)
            .await
            .map_err(|e| bind_error(e.to_string()))?;
        let local = listener
            .local_addr()
            .map_err(|e| bind_error(e.to_string()))?;
        on_ready(local);
        axum::serve(listener, app::router(state))
            .await
            .map_err(|e| bind_error(e.to_string()))
    })
}
