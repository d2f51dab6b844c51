//! The app as the API tests run it: its options, requests sent to its
//! router in memory (no socket), and what the tests read from the answers.

// Each test binary uses its own share of these.
#![allow(dead_code)]

use axum::body::Body;
use axum::http::{Request, StatusCode};
use matseg_serve::ServeOptions;
use std::path::PathBuf;
use tower::ServiceExt;

/// The web app on the shipped model over `data` and `bench`, on any free
/// port, with a small cache of described photos.
pub fn options(data: Vec<PathBuf>, bench: Vec<PathBuf>) -> ServeOptions {
    ServeOptions {
        data,
        bench,
        port: 0,
        cache_mb: 64,
        ..ServeOptions::default()
    }
}

/// Status, content type and body of the answer to `request`.
pub async fn send(app: &axum::Router, request: Request<Body>) -> (StatusCode, String, Vec<u8>) {
    let response = app.clone().oneshot(request).await.unwrap();
    let status = response.status();
    let kind = response
        .headers()
        .get("content-type")
        .map(|v| v.to_str().unwrap().to_string())
        .unwrap_or_default();
    let body = axum::body::to_bytes(response.into_body(), usize::MAX)
        .await
        .unwrap()
        .to_vec();
    (status, kind, body)
}

/// Status, content type and body of `GET uri`.
pub async fn get(app: &axum::Router, uri: &str) -> (StatusCode, String, Vec<u8>) {
    send(app, Request::get(uri).body(Body::empty()).unwrap()).await
}

/// Status, content type and body of `POST uri` with `body`.
pub async fn post(
    app: &axum::Router,
    uri: &str,
    body: impl Into<Body>,
) -> (StatusCode, String, Vec<u8>) {
    send(app, Request::post(uri).body(body.into()).unwrap()).await
}

/// A body read as JSON.
pub fn json(body: &[u8]) -> serde_json::Value {
    serde_json::from_slice(body).unwrap()
}

/// The one-line error of a refused request.
pub fn error_of(body: &[u8]) -> String {
    json(body)["error"].as_str().unwrap().to_string()
}
