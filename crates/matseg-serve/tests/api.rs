//! The API on the shipped model, through the router (no socket): the page
//! and its files, the photo list, photos, similarity maps and segmentations
//! of bundled photos, refused paths, bad points and the token.

use axum::body::Body;
use axum::http::{Request, StatusCode};
use matseg_serve::{app::router, state, ServeError, ServeOptions};
use tower::ServiceExt;

fn options() -> ServeOptions {
    ServeOptions {
        model: "default".into(),
        data: Vec::new(),
        host: "127.0.0.1".into(),
        port: 0,
        token: None,
        cache_mb: 64,
        device: tch::Device::Cpu,
    }
}

/// Status, content type and body of `GET uri`.
async fn get(app: &axum::Router, uri: &str) -> (StatusCode, String, Vec<u8>) {
    let response = app
        .clone()
        .oneshot(Request::get(uri).body(Body::empty()).unwrap())
        .await
        .unwrap();
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

fn error_of(body: &[u8]) -> String {
    let json: serde_json::Value = serde_json::from_slice(body).unwrap();
    json["error"].as_str().unwrap().to_string()
}

#[tokio::test(flavor = "multi_thread")]
async fn a_click_is_answered_with_the_material_under_it() {
    let app = router(state(&options()).unwrap());
    let (status, kind, page) = get(&app, "/").await;
    assert_eq!(
        (status, kind.as_str()),
        (StatusCode::OK, "text/html; charset=utf-8")
    );
    assert!(String::from_utf8(page).unwrap().contains("/app.js"));
    assert_eq!(get(&app, "/app.js").await.0, StatusCode::OK);

    let (status, _, listing) = get(&app, "/api/photos").await;
    assert_eq!(status, StatusCode::OK);
    let listing: serde_json::Value = serde_json::from_slice(&listing).unwrap();
    let names: Vec<&str> = listing["photos"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["path"].as_str().unwrap())
        .collect();
    assert!(names.contains(&"coffee.jpg"), "{names:?}");
    assert_eq!(listing["total"].as_u64().unwrap() as usize, names.len());

    let (status, kind, jpeg) = get(&app, "/api/photo?root=photos&path=coffee.jpg").await;
    assert_eq!((status, kind.as_str()), (StatusCode::OK, "image/jpeg"));
    let photo = image::load_from_memory(&jpeg).unwrap().to_rgb8();

    // The coffee in the cup: similar to itself, not to the table's wood.
    let (status, kind, png) = get(
        &app,
        "/api/similarity?root=photos&path=coffee.jpg&points=290,130",
    )
    .await;
    assert_eq!((status, kind.as_str()), (StatusCode::OK, "image/png"));
    let map = image::load_from_memory(&png).unwrap().to_luma8();
    assert_eq!(map.dimensions(), photo.dimensions());
    assert!(map.get_pixel(290, 130).0[0] > 200);
    assert!(map.get_pixel(290, 130).0[0] > map.get_pixel(540, 80).0[0]);

    // Two points: each pixel takes its nearest point's label.
    let (status, _, png) = get(
        &app,
        "/api/segment?root=photos&path=coffee.jpg&points=290,130;540,80",
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    let labels = image::load_from_memory(&png).unwrap().to_luma8();
    assert_eq!(labels.get_pixel(290, 130).0[0], 0);
    assert_eq!(labels.get_pixel(540, 80).0[0], 1);
}

#[tokio::test(flavor = "multi_thread")]
async fn paths_outside_the_folders_bad_points_and_missing_tokens_are_refused() {
    let app = router(state(&options()).unwrap());
    for path in ["../LICENSES.md", "%2e%2e/LICENSES.md", "/etc/passwd"] {
        let (status, _, body) = get(&app, &format!("/api/photo?root=photos&path={path}")).await;
        assert_eq!(status, StatusCode::FORBIDDEN, "{path}");
        assert!(error_of(&body).contains("outside the served folders"));
    }
    let (status, _, _) = get(&app, "/api/photo?root=nowhere&path=a.jpg").await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    let (status, _, body) = get(
        &app,
        "/api/similarity?root=photos&path=coffee.jpg&points=9999,1",
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(
        error_of(&body).contains("outside coffee.jpg"),
        "{}",
        error_of(&body)
    );
    let (status, _, body) = get(&app, "/api/segment?root=photos&path=coffee.jpg&points=a,b").await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(error_of(&body).contains("expected X,Y"));

    let guarded = router(
        state(&ServeOptions {
            token: Some("s3cret".into()),
            ..options()
        })
        .unwrap(),
    );
    assert_eq!(
        get(&guarded, "/api/photos").await.0,
        StatusCode::UNAUTHORIZED
    );
    assert_eq!(
        get(&guarded, "/api/photos?token=s3cret").await.0,
        StatusCode::OK
    );
    // The page itself needs no token; the API does.
    assert_eq!(get(&guarded, "/").await.0, StatusCode::OK);

    let open = state(&ServeOptions {
        host: "0.0.0.0".into(),
        ..options()
    });
    assert!(matches!(open, Err(ServeError::NoToken(_))));
}
