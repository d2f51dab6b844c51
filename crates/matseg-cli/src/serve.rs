//! `matseg serve`: the local web app (`matseg_serve`; docs/serve.md).

use crate::net_args::parse_device;
use anyhow::Result;
use matseg_serve::{serve, ServeOptions, TokenChoice};
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
    /// Address to bind (the loopback unless told otherwise).
    #[arg(long, default_value = ServeOptions::HOST)]
    host: String,
    /// Another name the server answers to (the Host of a request), besides
    /// localhost, 127.0.0.1, [::1] and --host; repeatable.
    #[arg(long = "allowed-host", value_name = "NAME")]
    allowed_hosts: Vec<String>,
    /// Port (0: any free one).
    #[arg(long, default_value_t = ServeOptions::PORT)]
    port: u16,
    /// The token every API call must carry (header `x-matseg-token` or
    /// query `token`), instead of a new random one each run: 8 characters
    /// or more of A-Z a-z 0-9 . _ ~ -.
    #[arg(long, conflicts_with = "no_token")]
    token: Option<String>,
    /// No token: any page of this machine's browser that passes the
    /// Host and Origin checks may call the API (loopback only).
    #[arg(long)]
    no_token: bool,
    /// Bound on the described photos kept in memory, in MiB.
    #[arg(long, default_value_t = ServeOptions::CACHE_MB)]
    cache_mb: usize,
    /// Bound on the uploads on disk (photos and videos, arriving and
    /// kept), in MiB; the least recently used go first.
    #[arg(long, default_value_t = ServeOptions::UPLOAD_MB)]
    upload_mb: usize,
    /// cpu, cuda or cuda:N.
    #[arg(long, default_value = "cpu")]
    device: String,
    /// Announce the address as one JSON line, `{"address": "HOST:PORT",
    /// "url": "http://...", "token": ...}`, instead of the banner: for
    /// scripts that start the server with `--port 0`.
    #[arg(long)]
    json: bool,
}

/// Runs `matseg serve` until interrupted (SIGINT or SIGTERM).
pub fn run(args: Args) -> Result<()> {
    let token = match (args.token, args.no_token) {
        (Some(token), _) => TokenChoice::Given(token),
        (None, true) => TokenChoice::Off,
        (None, false) => TokenChoice::PerRun,
    };
    let options = ServeOptions {
        model: args.model,
        data: args.data,
        bench: args.bench,
        host: args.host,
        allowed_hosts: args.allowed_hosts,
        port: args.port,
        token,
        cache_mb: args.cache_mb,
        upload_mb: args.upload_mb,
        device: parse_device(&args.device)?,
    };
    serve(&options, |ready| {
        if args.json {
            let line = serde_json::json!({
                "address": ready.address.to_string(),
                "url": ready.url,
                "token": ready.token,
            });
            println!("{line}");
        } else {
            println!("matseg serve: {}", ready.url);
        }
    })?;
    Ok(())
}
