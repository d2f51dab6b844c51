//! The app as the API tests run it: its options, requests sent to its
//! router in memory (no socket) as its own pages send them (its Host, its
//! token, typed POST bodies), and what the tests read from the answers.

// Each test binary uses its own share of these.
#![allow(dead_code)]

use axum::body::Body;
use axum::http::{Request, StatusCode};
use image::{GrayImage, RgbImage};
use matseg_data::encode::EncodedSample;
use matseg_image::io::{encode_jpeg, encode_png_grey};
use matseg_serve::{ServeOptions, TokenChoice};
use std::path::PathBuf;
use tower::ServiceExt;

/// The token the test apps want.
pub const TOKEN: &str = "test-token";

/// The Host the test apps' pages send.
pub const HOST: &str = "127.0.0.1:8080";

/// The web app on the shipped model over `data` and `bench`, on any free
/// port, with a small cache of described photos, wanting [`TOKEN`].
pub fn options(data: Vec<PathBuf>, bench: Vec<PathBuf>) -> ServeOptions {
    ServeOptions {
        data,
        bench,
        port: 0,
        cache_mb: 64,
        token: TokenChoice::Given(TOKEN.into()),
        ..ServeOptions::default()
    }
}

/// Status, content type and body of the answer to `request`, sent as the
/// app's own page sends it: [`HOST`] and [`TOKEN`] added where the request
/// has none.
pub async fn send(app: &axum::Router, mut request: Request<Body>) -> (StatusCode, String, Vec<u8>) {
    let headers = request.headers_mut();
    headers.entry("host").or_insert(HOST.parse().unwrap());
    headers
        .entry("x-matseg-token")
        .or_insert(TOKEN.parse().unwrap());
    send_as_is(app, request).await
}

/// Status, content type and body of the answer to `request`, with nothing
/// added: a request another page, or another program, could send.
pub async fn send_as_is(
    app: &axum::Router,
    request: Request<Body>,
) -> (StatusCode, String, Vec<u8>) {
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

/// Status, content type and body of `POST uri` with `body`, typed as the
/// pages type it: `application/octet-stream` for uploads, JSON otherwise.
pub async fn post(
    app: &axum::Router,
    uri: &str,
    body: impl Into<Body>,
) -> (StatusCode, String, Vec<u8>) {
    let kind = if uri.contains("/upload") {
        "application/octet-stream"
    } else {
        "application/json"
    };
    let request = Request::post(uri).header("content-type", kind);
    send(app, request.body(body.into()).unwrap()).await
}

/// A body read as JSON.
pub fn json(body: &[u8]) -> serde_json::Value {
    serde_json::from_slice(body).unwrap()
}

/// The one-line error of a refused request.
pub fn error_of(body: &[u8]) -> String {
    json(body)["error"].as_str().unwrap().to_string()
}

/// Sample `index`: a 32 x 24 image, mask 0 a ramp left to right, mask 1
/// its complement.
pub fn sample(index: u64) -> EncodedSample {
    let ramp = GrayImage::from_fn(32, 24, |x, _| image::Luma([(x * 8) as u8]));
    let rest = GrayImage::from_fn(32, 24, |x, _| image::Luma([255 - (x * 8) as u8]));
    let image = RgbImage::from_fn(32, 24, |x, y| {
        image::Rgb([x as u8 * 8, y as u8 * 10, index as u8])
    });
    EncodedSample {
        index,
        jpg: encode_jpeg(&image, 90),
        masks: vec![
            encode_png_grey(32, 24, ramp.as_raw()),
            encode_png_grey(32, 24, rest.as_raw()),
        ],
        roi: encode_png_grey(32, 24, &[255; 32 * 24]),
        json: format!("{{\"seed\": 7, \"index\": {index}}}").into_bytes(),
    }
}
