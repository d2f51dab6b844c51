//! The API on the shipped model, through the router (no socket): the pages
//! and their files, the photo list, photos, similarity maps, segmentations
//! by points and automatic ones, uploads (and the refused ones), refused
//! paths, bad points and the token.

mod router;

use axum::body::Body;
use axum::http::Request;
use axum::http::StatusCode;
use matseg_serve::{app::router, state, ServeError, ServeOptions, TokenChoice};
use router::{error_of, get, json, post, send_as_is};

/// The web app on the shipped model and the bundled photos alone.
fn options() -> ServeOptions {
    router::options(Vec::new(), Vec::new())
}

#[tokio::test(flavor = "multi_thread")]
async fn a_click_is_answered_with_the_material_under_it() {
    let app = router(state(&options()).unwrap());
    let (status, kind, page) = get(&app, "/").await;
    assert_eq!(
        (status, kind.as_str()),
        (StatusCode::OK, "text/html; charset=utf-8")
    );
    assert!(String::from_utf8(page).unwrap().contains("/segment.js"));
    for file in [
        "/segment.js",
        "/common.js",
        "/style.css",
        "/browse",
        "/annotate",
        "/evaluate",
    ] {
        assert_eq!(get(&app, file).await.0, StatusCode::OK, "{file}");
    }
    assert_eq!(get(&app, "/nothing.js").await.0, StatusCode::NOT_FOUND);

    let (status, _, listing) = get(&app, "/api/photos").await;
    assert_eq!(status, StatusCode::OK);
    let listing = json(&listing);
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

    // Two points: each pixel takes its most similar point's label (red),
    // with its similarity to it (green).
    let (status, _, png) = get(
        &app,
        "/api/segment?root=photos&path=coffee.jpg&points=290,130;540,80",
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    let labels = image::load_from_memory(&png).unwrap().to_rgb8();
    assert_eq!(labels.dimensions(), photo.dimensions());
    assert_eq!(labels.get_pixel(290, 130).0[0], 0);
    assert_eq!(labels.get_pixel(540, 80).0[0], 1);
    assert_eq!(
        labels.get_pixel(290, 130).0[1],
        map.get_pixel(290, 130).0[0],
        "the strength is the similarity to the pixel's point"
    );
    assert!(labels.pixels().all(|p| p.0[0] <= 1 && p.0[2] == 0));
}

#[tokio::test(flavor = "multi_thread")]
async fn the_automatic_segmentation_splits_the_photo_into_k_materials() {
    let app = router(state(&options()).unwrap());
    let (status, _, png) = get(&app, "/api/auto?root=photos&path=coffee.jpg&k=3").await;
    assert_eq!(status, StatusCode::OK);
    let labels = image::load_from_memory(&png).unwrap().to_rgb8();
    assert_eq!(labels.dimensions(), (600, 400));
    let mut seen = [false; 3];
    for p in labels.pixels() {
        assert!(p.0[0] < 3 && p.0[1] == 255, "{:?}", p.0);
        seen[p.0[0] as usize] = true;
    }
    assert_eq!(seen, [true; 3], "three materials on the coffee photo");
    for k in [0, 21] {
        let (status, _, body) = get(
            &app,
            &format!("/api/auto?root=photos&path=coffee.jpg&k={k}"),
        )
        .await;
        assert_eq!(status, StatusCode::BAD_REQUEST);
        assert!(error_of(&body).contains("give 1 to 20 clusters"));
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn uploads_are_described_and_bad_ones_refused_with_a_reason() {
    let app_state = state(&options()).unwrap();
    let app = router(app_state.clone());
    let coffee =
        std::fs::read(matseg_pipeline::sources::assets_dir().join("photos/coffee.jpg")).unwrap();
    let (status, _, body) = post(&app, "/api/upload?name=mine.jpg", coffee.clone()).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    let upload = json(&body);
    assert_eq!(
        (upload["width"].as_u64(), upload["height"].as_u64()),
        (Some(600), Some(400))
    );
    let path = upload["path"].as_str().unwrap();
    let (status, kind, bytes) = get(&app, &format!("/api/photo?root=upload&path={path}")).await;
    assert_eq!(
        (status, kind.as_str(), bytes),
        (StatusCode::OK, "image/jpeg", coffee.clone())
    );
    // The upload's map is the bundled photo's: same pixels, same answer.
    let (_, _, uploaded) = get(
        &app,
        &format!("/api/similarity?root=upload&path={path}&points=290,130"),
    )
    .await;
    let (_, _, bundled) = get(
        &app,
        "/api/similarity?root=photos&path=coffee.jpg&points=290,130",
    )
    .await;
    assert_eq!(uploaded, bundled);

    let (status, _, body) =
        post(&app, "/api/upload?name=notes.txt", b"not an image".to_vec()).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(error_of(&body), "notes.txt: not a PNG or JPEG image");
    let (status, _, body) = post(
        &app,
        "/api/upload?name=cut.jpg",
        coffee[..coffee.len() / 2].to_vec(),
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error_of(&body),
        "cut.jpg: truncated JPEG: the file ends before its end-of-image marker"
    );
    let (status, _, body) = post(&app, "/api/upload?name=big.png", vec![0; (32 << 20) + 1]).await;
    assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE);
    assert_eq!(
        error_of(&body),
        "upload of 32.0 MiB (33554433 bytes): larger than 32 MiB, the most one may have"
    );
    let huge = matseg_image::io::encode_png_grey(8000, 6000, &vec![0; 8000 * 6000]);
    let (status, _, body) = post(&app, "/api/upload?name=huge.png", huge).await;
    assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE);
    assert_eq!(
        error_of(&body),
        "huge.png: 8000 x 6000 is 48.0 megapixels; the limit is 40"
    );
    let (status, _, body) = get(&app, "/api/photo?root=upload&path=0000000000000000.png").await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    // On disk: the one upload kept, nothing of the refused ones.
    let kept: Vec<_> = std::fs::read_dir(app_state.folder.path().join("uploads"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(kept, [path]);
    let (_, _, status) = get(&app, "/api/status").await;
    let status = json(&status);
    assert_eq!(
        status["uploads_mib"].as_f64().unwrap() * (1 << 20) as f64,
        coffee.len() as f64
    );
    assert_eq!(status["uploads_bound_mib"], 2048.0);
    assert!(error_of(&body).contains("upload it again"));
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

    // Without the token, with another one, or from the page without it.
    let with_headers = |pairs: &[(&str, &str)]| {
        let mut request = Request::get("/api/photos");
        for (name, value) in pairs {
            request = request.header(*name, *value);
        }
        request.body(Body::empty()).unwrap()
    };
    let host = ("host", router::HOST);
    for refused in [vec![host], vec![host, ("x-matseg-token", "guess")]] {
        let (status, _, body) = send_as_is(&app, with_headers(&refused)).await;
        assert_eq!(status, StatusCode::UNAUTHORIZED);
        assert!(error_of(&body).contains("token"), "{}", error_of(&body));
    }
    let (status, _, _) = send_as_is(
        &app,
        Request::get(format!("/api/photos?token={}", router::TOKEN))
            .header("host", router::HOST)
            .body(Body::empty())
            .unwrap(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    // The page itself needs no token; the API does.
    let (status, _, _) = send_as_is(
        &app,
        Request::get("/")
            .header("host", router::HOST)
            .body(Body::empty())
            .unwrap(),
    )
    .await;
    assert_eq!(status, StatusCode::OK);

    // By default a new token each run; none only when asked, on loopback.
    let per_run = |host: &str| {
        state(&ServeOptions {
            host: host.into(),
            token: TokenChoice::PerRun,
            ..options()
        })
    };
    let (a, b) = (per_run("127.0.0.1").unwrap(), per_run("0.0.0.0").unwrap());
    let (a, b) = (
        a.access.token.clone().unwrap(),
        b.access.token.clone().unwrap(),
    );
    assert_eq!(a.len(), 32);
    assert_ne!(a, b);
    let open = state(&ServeOptions {
        host: "0.0.0.0".into(),
        token: TokenChoice::Off,
        ..options()
    });
    assert!(matches!(open, Err(ServeError::NoToken(_))));
    let off = state(&ServeOptions {
        token: TokenChoice::Off,
        ..options()
    })
    .unwrap();
    assert!(off.access.token.is_none());
}

#[tokio::test(flavor = "multi_thread")]
async fn a_negative_click_leaves_its_material_out_of_the_selection() {
    let app = router(state(&options()).unwrap());
    let selected = |png: &[u8]| image::load_from_memory(png).unwrap().to_rgb8();
    // The coffee clicked: the method's own mask (green) takes the coffee
    // and, on this photo, the red saucer too; the soft map (red) is the
    // one-click similarity map.
    let (status, kind, png) = get(
        &app,
        "/api/select?root=photos&path=coffee.jpg&positive=290,130",
    )
    .await;
    assert_eq!((status, kind.as_str()), (StatusCode::OK, "image/png"));
    let coffee = selected(&png);
    assert_eq!(coffee.dimensions(), (600, 400));
    assert_eq!(coffee.get_pixel(290, 130).0[1], 255, "the clicked pixel");
    assert!(coffee
        .pixels()
        .all(|p| matches!(p.0[1], 0 | 255) && p.0[2] == 0));
    let (_, _, grey) = get(
        &app,
        "/api/similarity?root=photos&path=coffee.jpg&points=290,130",
    )
    .await;
    let grey = image::load_from_memory(&grey).unwrap().to_luma8();
    assert!(coffee
        .pixels()
        .zip(grey.pixels())
        .all(|(c, g)| c.0[0] == g.0[0]));
    let area = |image: &image::RgbImage| image.pixels().filter(|p| p.0[1] == 255).count();
    // The saucer clicked as negative: out of the mask, the coffee kept.
    let (status, _, png) = get(
        &app,
        "/api/select?root=photos&path=coffee.jpg&positive=290,130&negative=150,300",
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    let refined = selected(&png);
    assert_eq!(refined.get_pixel(150, 300).0[1], 0, "the negative's pixel");
    assert_eq!(refined.get_pixel(290, 130).0[1], 255);
    assert!(area(&refined) < area(&coffee), "the selection shrinks");
    assert!(refined.get_pixel(150, 300).0[0] < coffee.get_pixel(150, 300).0[0]);
}

#[tokio::test(flavor = "multi_thread")]
async fn bad_clicks_are_refused_naming_their_argument() {
    let app = router(state(&options()).unwrap());
    let photo = "/api/select?root=photos&path=coffee.jpg";
    let many = vec!["1,1"; 300].join(";");
    for (query, said) in [
        (
            "&negative=5,5",
            "positive: give one positive click at least",
        ),
        ("", "positive: give one positive click at least"),
        (
            "&positive=5,5&negative=a,b",
            "negative \"a,b\": expected X,Y",
        ),
        (
            "&positive=9999,1",
            "positive 9999,1: outside coffee.jpg (600x400)",
        ),
        (
            "&positive=5,5&negative=5,400",
            "negative 5,400: outside coffee.jpg",
        ),
        (
            &format!("&positive={many}"),
            "positive, negative: 300 clicks; at most 255",
        ),
        ("&positive=5,5&radius=-1", "radius"),
    ] {
        let (status, _, body) = get(&app, &format!("{photo}{query}")).await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{query}");
        assert!(
            error_of(&body).contains(said),
            "{query}: {}",
            error_of(&body)
        );
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn a_selection_is_saved_as_its_clicks_descriptors() {
    let app = router(state(&options()).unwrap());
    let (status, kind, body) = get(
        &app,
        "/api/select/save?root=photos&path=coffee.jpg&positive=290,130&negative=150,300;540,80",
    )
    .await;
    assert_eq!(
        (status, kind.as_str()),
        (StatusCode::OK, "application/json")
    );
    let saved: matseg_query::select::SavedSelection = serde_json::from_slice(&body).unwrap();
    assert_eq!(saved.model, "default");
    assert_eq!((saved.positive.len(), saved.negative.len()), (1, 2));
    assert_eq!(
        (saved.positive_colours.len(), saved.negative_colours.len()),
        (1, 2)
    );
    let dim = saved.positive[0].len();
    assert!(dim > 0);
    saved.check(dim).unwrap();
    let (status, _, body) = get(
        &app,
        "/api/select/save?root=photos&path=coffee.jpg&negative=150,300",
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(error_of(&body).starts_with("positive:"));
}
