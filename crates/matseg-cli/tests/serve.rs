//! `matseg serve` as a process: the address it prints carries its token,
//! a stop (SIGTERM, or Ctrl-C's SIGINT) in the middle of an evaluation
//! stops it and leaves no temporary folder behind, and settings it cannot
//! serve (an open address without a token, a token too short or not
//! URL-safe, a benchmark without images) are one-line errors.
#![cfg(feature = "net")]

mod common;

use common::*;
use matseg_serve::load::{Connection, ServerAddress};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// `matseg serve --json --port 0 EXTRA...` with its temporary files under
/// `tmp`; the process and where it listens.
fn start(tmp: &Path, extra: &[&str]) -> (Child, ServerAddress) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_matseg"))
        .args(["serve", "--json", "--port", "0"])
        .args(extra)
        .env("TMPDIR", tmp)
        .env("MATSEG_CACHE", test_cache())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let ready: serde_json::Value = serde_json::from_str(&line).unwrap();
    let token = ready["token"].as_str().unwrap().to_string();
    assert_eq!(token.len(), 32, "a new token each run: {line}");
    assert!(ready["url"]
        .as_str()
        .unwrap()
        .ends_with(&format!("/?token={token}")));
    let address = ServerAddress {
        host: ready["address"].as_str().unwrap().to_string(),
        token: Some(token),
    };
    (child, address)
}

/// The server's temporary folders under `tmp`.
fn server_folders(tmp: &Path) -> Vec<String> {
    std::fs::read_dir(tmp)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("matseg-serve-"))
        .collect()
}

/// Waits up to `limit` for `child` to end; its exit code.
fn wait(child: &mut Child, limit: Duration) -> Option<i32> {
    let started = Instant::now();
    while started.elapsed() < limit {
        if let Some(status) = child.try_wait().unwrap() {
            return status.code();
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = child.kill();
    None
}

#[test]
fn a_stopped_server_stops_its_jobs_and_removes_its_folder() {
    let bench = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../benchmarks/real-dev");
    let coffee = std::fs::read(Path::new(&assets("photos")).join("coffee.jpg")).unwrap();
    for signal in [libc::SIGTERM, libc::SIGINT] {
        let tmp = tempfile::tempdir().unwrap();
        let (mut child, address) = start(tmp.path(), &["--bench", bench.to_str().unwrap()]);
        assert_eq!(server_folders(tmp.path()).len(), 1);
        let mut connection = Connection::open(&address).unwrap();
        // Something in its folder, and a long job running.
        let (answer, body) = connection
            .send_body(
                "POST",
                "/api/upload?name=coffee.jpg",
                Some("image/jpeg"),
                &coffee,
            )
            .unwrap();
        assert_eq!(answer.status, 200, "{}", String::from_utf8_lossy(&body));
        let (answer, _) = connection
            .send(
                "POST",
                "/api/evaluate?root=bench0&baselines=rgb,lab,texture,position",
            )
            .unwrap();
        assert_eq!(answer.status, 200);
        let started = Instant::now();
        loop {
            let (_, body) = connection.get_body("/api/evaluate?root=bench0").unwrap();
            let state: serde_json::Value = serde_json::from_slice(&body).unwrap();
            assert_eq!(state["state"], "running", "{state}");
            if state["done"].as_u64().unwrap() > 0 {
                assert!(state["total"].as_u64().unwrap() > state["done"].as_u64().unwrap());
                break;
            }
            assert!(
                started.elapsed() < Duration::from_secs(120),
                "no image scored"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        // SAFETY: a signal to the child process this test started.
        assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
        let code = wait(&mut child, Duration::from_secs(60));
        assert_eq!(code, Some(0), "signal {signal}: a clean stop");
        assert_eq!(
            server_folders(tmp.path()),
            Vec::<String>::new(),
            "signal {signal}"
        );
    }
}

#[test]
fn serve_refuses_an_open_address_without_a_token_an_unusable_token_and_a_bench_without_images() {
    let open = matseg(&["serve", "--host", "0.0.0.0", "--port", "0", "--no-token"]);
    assert_one_line_error(
        &open,
        "--host 0.0.0.0: serving beyond this machine needs a token (leave out --no-token)",
    );
    let both = matseg(&["serve", "--token", "t", "--no-token"]);
    assert!(!both.status.success());
    for (token, said) in [
        ("", "--token: too short (0 of at least 8 characters"),
        ("a", "--token: too short (1 of at least 8 characters"),
        (" ", "--token: ' ' is not a URL-safe character"),
        ("secret token", "--token: ' ' is not a URL-safe character"),
        ("s3cret/tok", "--token: '/' is not a URL-safe character"),
    ] {
        let refused = matseg(&["serve", "--port", "0", "--token", token]);
        assert_one_line_error(&refused, said);
    }
    let dir = tempfile::tempdir().unwrap();
    let bench = matseg(&[
        "serve",
        "--port",
        "0",
        "--bench",
        dir.path().to_str().unwrap(),
    ]);
    assert_one_line_error(&bench, "a benchmark folder needs an images/ folder");
}
