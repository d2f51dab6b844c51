//! `matseg serve`: the local web app (`matseg_serve`; docs/serve.md).

use crate::net_args::parse_device;
use anyhow::Result;
use matseg_serve::{serve, ServeOptions};
use std::path::PathBuf;

/// Arguments of `matseg serve`.
#[derive(clap::Args)]
pub struct Args {
    /// The model: `default` (the shipped one), a run folder of `matseg
    /// train`, or its weights file.
    #[arg(long, default_value = "default")]
    model: PathBuf,
    /// Folders of photos to offer besides the bundled ones, or of datasets
    /// (MatSeg sample folders or WebDataset shards) to browse; repeatable.
    #[arg(long, num_args = 1..)]
    data: Vec<PathBuf>,
    /// Point benchmark folders (images/, data/NAME/data.json) to annotate
    /// and evaluate; repeatable.
    #[arg(long, num_args = 1..)]
    bench: Vec<PathBuf>,
    /// Address to bind; any other than the loopback needs --token.
    #[arg(long, default_value = ServeOptions::HOST)]
    host: String,
    /// Port (0: any free one).
    #[arg(long, default_value_t = ServeOptions::PORT)]
    port: u16,
    /// A token every API call must carry (header `x-matseg-token` or
    /// query `token`).
    #[arg(long)]
    token: Option<String>,
    /// Bound on the described photos kept in memory, in MiB.
    #[arg(long, default_value_t = ServeOptions::CACHE_MB)]
    cache_mb: usize,
    /// cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Announce the address as one JSON line, `{"address": "HOST:PORT",
    /// "url": "http://..."}`, instead of the banner: for scripts that start
    /// the server with `--port 0`.
    #[arg(long)]
    json: bool,
}

/// Runs `matseg serve` until interrupted.
pub fn run(args: Args) -> Result<()> {
    let options = ServeOptions {
        model: args.model,
        data: args.data,
        bench: args.bench,
        host: args.host,
        port: args.port,
        token: args.token,
        cache_mb: args.cache_mb,
        device: parse_device(&args.device)?,
    };
    let token = options.token.clone();
    serve(&options, |address| {
        let query = token.map(|t| format!("?token={t}")).unwrap_or_default();
        let url = format!("http://{address}/{query}");
        if args.json {
            let line = serde_json::json!({ "address": address.to_string(), "url": url });
            println!("{line}");
        } else {
            println!("matseg serve: {url}");
        }
    })?;
    Ok(())
}
