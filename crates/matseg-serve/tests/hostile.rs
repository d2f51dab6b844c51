//! Hostile requests to every route of the API, through the router on the
//! shipped model: missing, malformed, out-of-range and huge parameters,
//! paths and names that leave the served folders, and empty, foreign,
//! truncated and oversized uploads. Each must be refused with a 4xx status
//! and a one-line JSON error, never a panic or a 5xx; nothing refused is
//! kept, and no file outside changed; and the server goes on answering.
//! Then what the router alone cannot show: a photo of many pixels and
//! few bytes described within the memory bound, an upload larger than
//! the whole uploads bound, unusable tokens, and requests that name a
//! second host (sent over a socket as raw HTTP).

mod ffmpeg;
mod router;

use axum::body::Body;
use axum::http::{Method, Request, StatusCode};
use ffmpeg::write_test_pattern;
use matseg_serve::{app::router, state};
use router::{options, sample, send};

/// A request, and the status it must get.
struct Hostile {
    method: Method,
    uri: String,
    body: Vec<u8>,
    status: StatusCode,
}

fn get(uri: impl Into<String>, status: StatusCode) -> Hostile {
    Hostile {
        method: Method::GET,
        uri: uri.into(),
        body: Vec::new(),
        status,
    }
}

fn post(uri: impl Into<String>, body: impl Into<Vec<u8>>, status: StatusCode) -> Hostile {
    Hostile {
        method: Method::POST,
        uri: uri.into(),
        body: body.into(),
        status,
    }
}

fn delete(uri: impl Into<String>, status: StatusCode) -> Hostile {
    Hostile {
        method: Method::DELETE,
        uri: uri.into(),
        body: Vec::new(),
        status,
    }
}

/// A black PNG of 42 megapixels (a few hundred KB), over the 40 an
/// upload may have.
fn huge_png() -> Vec<u8> {
    matseg_image::io::encode_png_grey(7000, 6000, &vec![0; 7000 * 6000])
}

fn requests(coffee: &[u8]) -> Vec<Hostile> {
    use StatusCode as S;
    let photo = "root=photos&path=coffee.jpg";
    let clip = "root=data1&path=clip.mkv";
    let many = vec!["1,1"; 300].join(";");
    let mut list = vec![
        // The photo list and photos.
        get("/api/photos?offset=-1", S::BAD_REQUEST),
        get("/api/photos?limit=lots", S::BAD_REQUEST),
        get("/api/photos?offset=99999999999999999999999", S::BAD_REQUEST),
        get("/api/photo", S::BAD_REQUEST),
        get("/api/photo?root=photos&path=../../../etc/passwd", S::FORBIDDEN),
        get("/api/photo?root=photos&path=%2e%2e%2f%2e%2e%2fLICENSE", S::FORBIDDEN),
        get("/api/photo?root=photos&path=/etc/passwd", S::FORBIDDEN),
        get("/api/photo?root=nowhere&path=a.jpg", S::NOT_FOUND),
        get("/api/photo?root=photos&path=licenses.json", S::BAD_REQUEST),
        get("/api/photo?root=upload&path=0123456789abcdef.png", S::NOT_FOUND),
        get("/api/photo?root=upload&path=../../etc/passwd", S::FORBIDDEN),
        get("/api/select?root=upload&path=..&positive=5,5", S::FORBIDDEN),
        get("/api/photo?root=data0&path=sample/99999", S::NOT_FOUND),
        get("/api/photo?root=data0&path=sample/x", S::BAD_REQUEST),
        // Clicks: points and radii.
        get(format!("/api/similarity?{photo}"), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points="), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points=a,b"), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points=1;2"), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points={many}"), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points=9999,1"), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points=-1,5"), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points=NaN,5"), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points=5,5&radius=-1"), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points=5,5&radius=NaN"), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points=5,5&radius=1e9"), S::BAD_REQUEST),
        get(format!("/api/similarity?{photo}&points=5,5&radius=big"), S::BAD_REQUEST),
        get(format!("/api/segment?{photo}&points=5,5"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&negative=5,5"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&positive=a,b"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&positive=5,5&negative=1;2"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&positive={many}"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&positive=5,5&negative={many}"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&positive=9999,1"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&positive=5,5&negative=-1,5"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&positive=NaN,5"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&positive=inf,5"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&positive=5,5&radius=NaN"), S::BAD_REQUEST),
        get(format!("/api/select?{photo}&positive=5,5&radius=1e9"), S::BAD_REQUEST),
        get("/api/select?root=photos&path=../../etc/passwd&positive=5,5", S::FORBIDDEN),
        get("/api/select?root=nowhere&path=a.jpg&positive=5,5", S::NOT_FOUND),
        get(format!("/api/select/save?{photo}"), S::BAD_REQUEST),
        get(format!("/api/select/save?{photo}&positive=9999,1"), S::BAD_REQUEST),
        get(format!("/api/select/save?{photo}&positive={many}"), S::BAD_REQUEST),
        get(format!("/api/auto?{photo}&k=0"), S::BAD_REQUEST),
        get(format!("/api/auto?{photo}&k=21"), S::BAD_REQUEST),
        get(format!("/api/auto?{photo}&k=-3"), S::BAD_REQUEST),
        get(format!("/api/auto?{photo}"), S::BAD_REQUEST),
        // Uploads: empty, foreign, cut short, huge, too large.
        post("/api/upload?name=empty.jpg", Vec::new(), S::BAD_REQUEST),
        post("/api/upload?name=notes.jpg", b"not a photo".to_vec(), S::BAD_REQUEST),
        post("/api/upload?name=cut.jpg", coffee[..coffee.len() / 2].to_vec(), S::BAD_REQUEST),
        post("/api/upload?name=huge.png", huge_png(), S::PAYLOAD_TOO_LARGE),
        post("/api/upload?name=big.jpg", vec![0xFF; (32 << 20) + 1], S::PAYLOAD_TOO_LARGE),
        // Datasets.
        get("/api/samples?root=nowhere", S::NOT_FOUND),
        get("/api/samples?root=data0&offset=x", S::BAD_REQUEST),
        get("/api/sample?root=data0&index=99999", S::NOT_FOUND),
        get("/api/sample?root=data0&index=-1", S::BAD_REQUEST),
        get("/api/sample/image?root=data0&index=0&part=secrets", S::BAD_REQUEST),
        get("/api/sample/image?root=data0&index=0&part=mask&mask=99", S::NOT_FOUND),
        // Annotations: a name is a plain name of a listed image.
        get("/api/annotation?root=bench0&name=../../etc/passwd", S::FORBIDDEN),
        get("/api/annotation?root=bench0&name=..%2F..%2Fetc%2Fpasswd", S::FORBIDDEN),
        get("/api/annotation?root=bench0&name=/etc/passwd", S::FORBIDDEN),
        get("/api/annotation?root=bench0&name=..", S::FORBIDDEN),
        get("/api/annotation?root=bench0&name=.", S::FORBIDDEN),
        get("/api/annotation?root=bench0&name=a%00b", S::FORBIDDEN),
        get("/api/annotation?root=bench0&name=", S::BAD_REQUEST),
        get("/api/annotation?root=bench0", S::BAD_REQUEST),
        get("/api/annotation?root=bench0&name=nothere", S::NOT_FOUND),
        get("/api/annotation?root=bench0&name=coffee.jpg", S::NOT_FOUND),
        post("/api/annotation?root=bench0&name=../coffee", br#"{"groups": []}"#.to_vec(), S::FORBIDDEN),
        post("/api/annotation?root=bench0&name=..", br#"{"groups": []}"#.to_vec(), S::FORBIDDEN),
        get("/api/annotation?root=nowhere&name=coffee", S::NOT_FOUND),
        post("/api/annotation?root=bench0&name=coffee", b"{not json".to_vec(), S::BAD_REQUEST),
        post("/api/annotation?root=bench0&name=coffee", b"".to_vec(), S::BAD_REQUEST),
        post(
            "/api/annotation?root=bench0&name=coffee",
            br#"{"groups": [{"id": "1", "points": [[9999, 1, 5]]}], "relations": []}"#.to_vec(),
            S::BAD_REQUEST,
        ),
        post(
            "/api/annotation?root=bench0&name=coffee",
            br#"{"groups": [{"id": "1", "points": [[5, 5, 1e9]]}], "relations": []}"#.to_vec(),
            S::BAD_REQUEST,
        ),
        post(
            "/api/annotation?root=bench0&name=coffee",
            br#"{"groups": [{"id": "1", "points": [[5, 5, 5]]}, {"id": "1", "points": [[6, 6, 5]]}], "relations": []}"#.to_vec(),
            S::BAD_REQUEST,
        ),
        post(
            "/api/annotation?root=bench0&name=coffee",
            vec![b' '; 3 << 20],
            S::PAYLOAD_TOO_LARGE,
        ),
        // Evaluations.
        post("/api/evaluate?root=nowhere", Vec::new(), S::NOT_FOUND),
        post("/api/evaluate?root=bench0&baselines=nope", Vec::new(), S::BAD_REQUEST),
        get("/api/evaluate?root=nowhere", S::NOT_FOUND),
        delete("/api/evaluate?root=nowhere", S::NOT_FOUND),
        // Videos and tracks.
        get("/api/video?root=data1&path=missing.mp4", S::NOT_FOUND),
        get("/api/video?root=data1&path=../clip.mkv", S::FORBIDDEN),
        get("/api/video?root=upload&path=../../clip.mkv", S::FORBIDDEN),
        get(format!("/api/video?{photo}"), S::BAD_REQUEST),
        get(format!("/api/video/frame?{clip}&frame=999999"), S::BAD_REQUEST),
        get(format!("/api/video/frame?{clip}&frame=-1"), S::BAD_REQUEST),
        post("/api/video/upload?name=empty.mp4", Vec::new(), S::BAD_REQUEST),
        post("/api/video/upload?name=notes.mp4", b"not a video".to_vec(), S::BAD_REQUEST),
        post("/api/video/upload?name=notes.txt", b"not a video".to_vec(), S::BAD_REQUEST),
        post("/api/video/upload", b"no name".to_vec(), S::BAD_REQUEST),
        post(format!("/api/track?{clip}&points="), Vec::new(), S::BAD_REQUEST),
        post(format!("/api/track?{clip}&points={many}"), Vec::new(), S::BAD_REQUEST),
        post(format!("/api/track?{clip}&points=500,5"), Vec::new(), S::BAD_REQUEST),
        post(format!("/api/track?{clip}&points=5,5&negative=500,5"), Vec::new(), S::BAD_REQUEST),
        post(format!("/api/track?{clip}&points=5,5&negative=a,b"), Vec::new(), S::BAD_REQUEST),
        post(format!("/api/track?{clip}&points=5,5&negative={many}"), Vec::new(), S::BAD_REQUEST),
        post(format!("/api/track?{clip}&points=5,5&frame=6"), Vec::new(), S::BAD_REQUEST),
        post(format!("/api/track?{clip}&points=5,5&radius=-1"), Vec::new(), S::BAD_REQUEST),
        post(format!("/api/track?{clip}&points=5,5&radius=NaN"), Vec::new(), S::BAD_REQUEST),
        get("/api/track?job=999", S::NOT_FOUND),
        get("/api/track?job=x", S::BAD_REQUEST),
        delete("/api/track?job=999", S::NOT_FOUND),
        get("/api/track/frame?job=999&frame=0", S::NOT_FOUND),
        get("/api/track/frame?job=1&frame=0&part=secrets", S::BAD_REQUEST),
        get("/api/track/download?job=999", S::NOT_FOUND),
        // No such route or method.
        get("/api/nothing", S::NOT_FOUND),
        delete("/api/photos", S::METHOD_NOT_ALLOWED),
    ];
    list.push(get("/nothing.js", S::NOT_FOUND));
    list
}

#[tokio::test(flavor = "multi_thread")]
async fn every_hostile_request_is_refused_in_one_line_and_nothing_is_kept() {
    let data = tempfile::tempdir().unwrap();
    matseg_data::folders::write_sample(data.path(), &sample(0)).unwrap();
    let videos = tempfile::tempdir().unwrap();
    write_test_pattern(&videos.path().join("clip.mkv"));
    let bench = tempfile::tempdir().unwrap();
    std::fs::create_dir(bench.path().join("images")).unwrap();
    let photos = matseg_pipeline::sources::assets_dir().join("photos");
    std::fs::copy(
        photos.join("coffee.jpg"),
        bench.path().join("images/coffee.jpg"),
    )
    .unwrap();
    let coffee = std::fs::read(photos.join("coffee.jpg")).unwrap();
    let served = options(
        vec![data.path().into(), videos.path().into()],
        vec![bench.path().into()],
    );
    let app_state = state(&served).unwrap();
    let app = router(app_state.clone());

    let mut wrong = Vec::new();
    let all = requests(&coffee);
    for hostile in &all {
        let kind = if hostile.uri.contains("/upload") {
            "application/octet-stream"
        } else {
            "application/json"
        };
        let request = Request::builder()
            .method(hostile.method.clone())
            .uri(&hostile.uri)
            .header("content-type", kind)
            .body(Body::from(hostile.body.clone()))
            .unwrap();
        let (status, content, body) = send(&app, request).await;
        let text = String::from_utf8_lossy(&body);
        let error = serde_json::from_slice::<serde_json::Value>(&body)
            .ok()
            .and_then(|v| v["error"].as_str().map(str::to_string));
        let shown: String = hostile.uri.chars().take(90).collect();
        match error {
            _ if status != hostile.status => wrong.push(format!(
                "{} {shown}: {status}, not {}: {text}",
                hostile.method, hostile.status
            )),
            Some(e) if content == "application/json" && !e.is_empty() && !e.contains('\n') => {}
            _ => wrong.push(format!(
                "{} {shown}: not a one-line JSON error: {text}",
                hostile.method
            )),
        }
    }
    assert!(
        wrong.is_empty(),
        "{} of {} hostile requests were not refused as they should be:\n{}",
        wrong.len(),
        all.len(),
        wrong.join("\n")
    );
    // Nothing refused is kept; nothing is running; the server goes on.
    let kept: Vec<_> = std::fs::read_dir(app_state.folder.path().join("uploads"))
        .unwrap()
        .collect();
    assert!(kept.is_empty(), "{kept:?}");
    assert!(!bench.path().join("data").exists(), "no annotation saved");
    let (status, _, body) = router::get(&app, "/api/evaluate?root=bench0").await;
    assert_eq!(
        (status, router::json(&body)["state"].clone()),
        (StatusCode::OK, "idle".into())
    );
    let (status, _, _) = router::get(
        &app,
        "/api/similarity?root=photos&path=coffee.jpg&points=5,5",
    )
    .await;
    assert_eq!(status, StatusCode::OK);
}

/// `text` with every byte but letters and digits percent-encoded, as a
/// query parameter's value.
fn encoded(text: &str) -> String {
    text.bytes()
        .map(|b| match b {
            b'a'..=b'z' | b'A'..=b'Z' | b'0'..=b'9' => (b as char).to_string(),
            _ => format!("%{b:02X}"),
        })
        .collect()
}

/// Every file under `dir` (symlinks not followed) with its bytes.
fn snapshot(dir: &std::path::Path) -> Vec<(String, Vec<u8>)> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let kind = std::fs::symlink_metadata(&path).unwrap().file_type();
        if kind.is_dir() {
            files.extend(snapshot(&path));
        } else if kind.is_symlink() {
            let target = std::fs::read_link(&path).unwrap();
            files.push((
                path.display().to_string(),
                target.display().to_string().into(),
            ));
        } else {
            files.push((path.display().to_string(), std::fs::read(&path).unwrap()));
        }
    }
    files.sort();
    files
}

#[tokio::test(flavor = "multi_thread")]
async fn annotation_names_that_leave_the_benchmark_change_and_show_nothing_outside() {
    // A user's files beside the benchmarks: an image and an annotation of
    // the same name as a benchmark's, and a file whose first line is
    // private.
    let top = tempfile::tempdir().unwrap();
    let elsewhere = top.path().join("elsewhere");
    let coffee = matseg_pipeline::sources::assets_dir().join("photos/coffee.jpg");
    std::fs::create_dir_all(elsewhere.join("balance")).unwrap();
    std::fs::create_dir_all(elsewhere.join("notes")).unwrap();
    for name in ["balance.jpg", "notes.jpg"] {
        std::fs::copy(&coffee, elsewhere.join(name)).unwrap();
    }
    std::fs::write(
        elsewhere.join("balance/data.json"),
        r#"{"1": {"pt_im": [[290, 130, 5]]}, "2": {"pt_im": [[540, 80, 5]]}}"#,
    )
    .unwrap();
    std::fs::write(elsewhere.join("balance/group_relations.txt"), "[1, 2]\n").unwrap();
    std::fs::write(
        elsewhere.join("notes/data.json"),
        "private: the first line\n",
    )
    .unwrap();
    std::fs::write(
        elsewhere.join("notes/group_relations.txt"),
        "private: the first line\n",
    )
    .unwrap();
    // Two benchmarks with images of those names: one plain, one whose
    // annotation folder is a symlink to the user's.
    let bench = top.path().join("x/bench");
    let linked = top.path().join("x/linked");
    for dir in [&bench, &linked] {
        std::fs::create_dir_all(dir.join("images")).unwrap();
        for name in ["balance.jpg", "notes.jpg"] {
            std::fs::copy(&coffee, dir.join("images").join(name)).unwrap();
        }
    }
    std::fs::create_dir(linked.join("data")).unwrap();
    std::os::unix::fs::symlink(elsewhere.join("balance"), linked.join("data/balance")).unwrap();
    std::os::unix::fs::symlink(elsewhere.join("notes"), linked.join("data/notes")).unwrap();
    let app_state = state(&options(Vec::new(), vec![bench.clone(), linked.clone()])).unwrap();
    let app = router(app_state.clone());
    let outside = snapshot(&elsewhere);
    let linked_before = snapshot(&linked);

    let one_group = r#"{"groups": [{"id": "1", "points": [[1, 1, 5]]}], "relations": []}"#;
    let no_groups = r#"{"groups": [], "relations": []}"#;
    let absolute = elsewhere.join("balance").display().to_string();
    let mut asked: Vec<(&str, String)> = [
        "../../../elsewhere/balance",
        "../../../elsewhere/notes",
        "balance/../../../../elsewhere/balance",
        "..\\..\\..\\elsewhere\\balance",
        absolute.as_str(),
    ]
    .into_iter()
    .map(|name| ("bench0", name.to_string()))
    .collect();
    asked.push(("bench1", "balance".into()));
    asked.push(("bench1", "notes".into()));
    let mut wrong = Vec::new();
    for (root, name) in &asked {
        let uri = format!("/api/annotation?root={root}&name={}", encoded(name));
        for (what, answer) in [
            ("write", router::post(&app, &uri, one_group).await),
            ("delete", router::post(&app, &uri, no_groups).await),
            ("read", router::get(&app, &uri).await),
        ] {
            let (status, _, body) = answer;
            let text = String::from_utf8_lossy(&body).into_owned();
            let one_line = serde_json::from_slice::<serde_json::Value>(&body)
                .ok()
                .and_then(|v| v["error"].as_str().map(|e| !e.contains('\n')))
                == Some(true);
            if status != StatusCode::FORBIDDEN || !one_line || text.contains("private") {
                wrong.push(format!("{what} {root} {name:?}: {status} {text}"));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "not refused with 403:\n{}",
        wrong.join("\n")
    );
    assert_eq!(
        snapshot(&elsewhere),
        outside,
        "the files outside are as they were"
    );
    assert_eq!(snapshot(&linked), linked_before);
    assert!(
        !bench.join("data").exists(),
        "nothing made in the benchmark"
    );
    // The listing does not read through the symlink either.
    let (_, _, listing) = router::get(&app, "/api/benches").await;
    let listing = router::json(&listing);
    let linked_images = listing["benches"][1]["images"].as_array().unwrap();
    assert_eq!(linked_images.len(), 2);
    assert!(linked_images.iter().all(|i| i["groups"] == 0), "{listing}");
    // The benchmark's own image is still annotated as before.
    let (status, _, body) =
        router::post(&app, "/api/annotation?root=bench0&name=balance", one_group).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    assert!(bench.join("data/balance/data.json").is_file());
    assert_eq!(snapshot(&elsewhere), outside);
}

/// A PNG of `width x height` (a few hundred KB): the left half one
/// colour, the right half another.
fn two_halves_png(width: u32, height: u32) -> Vec<u8> {
    let photo = image::RgbImage::from_fn(width, height, |x, _| {
        image::Rgb(if x < width / 2 {
            [200, 50, 30]
        } else {
            [30, 80, 200]
        })
    });
    matseg_image::io::encode_png_rgb(&photo)
}

#[tokio::test(flavor = "multi_thread")]
async fn a_photo_of_many_pixels_and_few_bytes_is_described_within_the_memory_bound() {
    let photos = tempfile::tempdir().unwrap();
    let (width, height) = (6000, 6000);
    let png = two_halves_png(width, height);
    assert!(png.len() < 2 << 20, "{} bytes", png.len());
    std::fs::write(photos.path().join("halves.png"), &png).unwrap();
    let bound_mib = 256;
    let app_state = state(&matseg_serve::ServeOptions {
        cache_mb: bound_mib,
        ..options(vec![photos.path().into()], Vec::new())
    })
    .unwrap();
    let app = router(app_state.clone());
    // Clicks on the left half, near its far corner: answered in the
    // photo's own pixels, the left half selected and not the right.
    let select =
        |x: u32, y: u32| format!("/api/select?root=data0&path=halves.png&positive={x},{y}");
    let (status, _, body) = router::get(&app, &select(2500, 5990)).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    let selected = image::load_from_memory(&body).unwrap().to_rgb8();
    assert_eq!(selected.dimensions(), (width, height));
    for (x, y) in [(100, 300), (2500, 5990), (1500, 3000), (2700, 10)] {
        assert_eq!(selected.get_pixel(x, y).0[1], 255, "{x},{y} selected");
    }
    for (x, y) in [(5999, 5999), (4500, 3000), (3300, 10)] {
        assert_eq!(selected.get_pixel(x, y).0[1], 0, "{x},{y} not selected");
    }
    // The similarity map too, and a click outside the photo's own pixels.
    let (status, _, body) = router::get(
        &app,
        "/api/similarity?root=data0&path=halves.png&points=5999,5999",
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    let grey = image::load_from_memory(&body).unwrap().to_luma8();
    assert_eq!(grey.dimensions(), (width, height));
    assert!(grey.get_pixel(5999, 5999).0[0] > grey.get_pixel(0, 0).0[0]);
    let (status, _, body) = router::get(&app, &select(6000, 10)).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(router::error_of(&body).contains("outside halves.png (6000x6000)"));
    // What it holds: one description, at the capped size, within the bound.
    let (_, _, answer) = router::get(&app, "/api/status").await;
    let held = router::json(&answer);
    let described_mib = held["described_mib"].as_f64().unwrap();
    assert!(
        described_mib > 0.0 && described_mib <= bound_mib as f64,
        "{held}"
    );
    let capped = app_state
        .model
        .described_bytes(matseg_serve::described::described_size(width, height));
    let uncapped = app_state.model.described_bytes((width, height));
    assert!(app_state.described.bytes() <= capped);
    assert!(capped < uncapped / 2, "{capped} of {uncapped} bytes");
    assert_eq!(app_state.budget.held(), app_state.described.bytes());
    // Uploaded, the same photo is taken and described the same way.
    let (status, _, body) = router::post(&app, "/api/upload?name=halves.png", png).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    let path = router::json(&body)["path"].as_str().unwrap().to_string();
    let (status, _, body) = router::get(
        &app,
        &format!("/api/select?root=upload&path={path}&positive=10,10"),
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    let uploaded = image::load_from_memory(&body).unwrap().to_rgb8();
    assert_eq!(uploaded.dimensions(), (width, height));
    assert_eq!(uploaded.get_pixel(5999, 0).0[1], 0);
    assert!(app_state.budget.held() <= bound_mib << 20);
}

#[tokio::test(flavor = "multi_thread")]
async fn a_photo_within_the_cap_is_answered_as_the_library_selects_it() {
    let app_state = state(&options(Vec::new(), Vec::new())).unwrap();
    let app = router(app_state.clone());
    let (status, _, served) = router::get(
        &app,
        "/api/select?root=photos&path=coffee.jpg&positive=290,130;300,150&negative=150,300&radius=7",
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    let photo = matseg_image::io::read_rgb(
        &matseg_pipeline::sources::assets_dir().join("photos/coffee.jpg"),
    )
    .unwrap();
    let net =
        matseg_pipeline::segment::load_model(std::path::Path::new("default"), Default::default())
            .unwrap();
    let map = matseg_pipeline::segment::describe(&net, &photo);
    use matseg_query::select::{Click, Selector};
    let mut selector = Selector::new(&map, Some(&photo), 7.0).unwrap();
    for click in [
        Click::positive(290.0, 130.0),
        Click::positive(300.0, 150.0),
        Click::negative(150.0, 300.0),
    ] {
        selector.add(click).unwrap();
    }
    let own = matseg_serve::select::selection_png(&selector.selection().unwrap());
    assert!(
        served == own,
        "the served selection is the library's, byte for byte"
    );
}

#[tokio::test(flavor = "multi_thread")]
async fn an_upload_larger_than_the_whole_uploads_bound_is_too_large() {
    let app_state = state(&matseg_serve::ServeOptions {
        upload_mb: 5,
        ..options(Vec::new(), Vec::new())
    })
    .unwrap();
    let app = router(app_state.clone());
    let big = vec![0xFF; 7_235_174];
    for uri in ["/api/upload?name=big.jpg", "/api/video/upload?name=big.mp4"] {
        let (status, _, body) = router::post(&app, uri, big.clone()).await;
        assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE, "{uri}");
        let error = router::error_of(&body);
        assert!(
            error.contains("6.9 MiB (7235174 bytes)")
                && error.contains("whole bound on uploads, 5 MiB (--upload-mb)"),
            "{uri}: {error}"
        );
    }
    let kept: Vec<_> = std::fs::read_dir(app_state.folder.path().join("uploads"))
        .unwrap()
        .collect();
    assert!(kept.is_empty(), "{kept:?}");
    assert_eq!(app_state.uploads.bytes(), 0);
}

#[test]
fn unusable_tokens_are_refused_naming_the_option() {
    for (token, said) in [
        ("a", "--token: too short (1 of at least 8 characters"),
        (" ", "--token: ' ' is not a URL-safe character"),
        (
            "long enough but spaced",
            "--token: ' ' is not a URL-safe character",
        ),
        ("", "--token: too short (0 of"),
    ] {
        let refused = state(&matseg_serve::ServeOptions {
            token: matseg_serve::TokenChoice::Given(token.into()),
            ..options(Vec::new(), Vec::new())
        });
        match refused {
            Err(e @ matseg_serve::ServeError::Token(_)) => {
                let message = e.to_string();
                assert!(message.starts_with(said), "{token:?}: {message}");
                assert!(!message.contains('\n'));
            }
            Err(e) => panic!("{token:?}: {e}"),
            Ok(_) => panic!("{token:?}: accepted"),
        }
    }
}

/// The status and body of `request` (raw HTTP/1.1, closed after the
/// answer) sent to `address`.
fn raw(address: std::net::SocketAddr, request: &[u8]) -> (u16, String) {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(address).unwrap();
    stream
        .set_read_timeout(Some(std::time::Duration::from_secs(60)))
        .unwrap();
    stream.write_all(request).unwrap();
    let mut answer = Vec::new();
    stream.read_to_end(&mut answer).unwrap();
    let answer = String::from_utf8_lossy(&answer);
    let status = answer
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no status: {answer:?}"));
    let body = answer.split_once("\r\n\r\n").map_or("", |(_, b)| b);
    (status, body.to_string())
}

/// `matseg serve` on a free port of the loopback, in a thread of its own,
/// stopped (and waited for) when dropped.
struct Running {
    address: std::net::SocketAddr,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    server: Option<std::thread::JoinHandle<Result<(), matseg_serve::ServeError>>>,
}

impl Running {
    fn start(served: matseg_serve::ServeOptions) -> Self {
        let (ready_send, ready) = std::sync::mpsc::channel();
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let server = std::thread::spawn(move || {
            matseg_serve::serve_until(
                &served,
                |ready| ready_send.send(ready.address).unwrap(),
                |_| async move {
                    let _ = stopped.await;
                },
            )
        });
        Self {
            address: ready.recv().unwrap(),
            stop: Some(stop),
            server: Some(server),
        }
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.stop.take().unwrap().send(());
        let stopped = self.server.take().unwrap().join();
        if !std::thread::panicking() {
            stopped.unwrap().unwrap();
        }
    }
}

#[test]
fn a_second_host_or_a_host_in_the_request_line_is_refused() {
    let running = Running::start(options(Vec::new(), Vec::new()));
    let address = running.address;
    let own = format!("127.0.0.1:{}", address.port());
    let own_absolute = format!("GET http://{own}/api/photos HTTP/1.1");
    let token = router::TOKEN;
    let ask = |line: &str, hosts: &[&str]| {
        let hosts: String = hosts.iter().map(|h| format!("Host: {h}\r\n")).collect();
        raw(
            address,
            format!("{line}\r\n{hosts}x-matseg-token: {token}\r\nConnection: close\r\n\r\n")
                .as_bytes(),
        )
    };
    // The page's own request is answered.
    let (status, body) = ask("GET /api/photos HTTP/1.1", &[&own]);
    assert_eq!(status, 200, "{body}");
    let mut wrong = Vec::new();
    for (line, hosts) in [
        (
            "GET /api/photos HTTP/1.1",
            vec![own.as_str(), "evil.example"],
        ),
        (
            "GET /api/photos HTTP/1.1",
            vec!["evil.example", own.as_str()],
        ),
        ("GET /api/photos HTTP/1.1", vec![own.as_str(), own.as_str()]),
        ("GET / HTTP/1.1", vec![own.as_str(), "evil.example"]),
        (
            "GET http://evil.example/api/photos HTTP/1.1",
            vec![own.as_str()],
        ),
        ("GET http://evil.example/ HTTP/1.1", vec![own.as_str()]),
        (
            "POST http://evil.example/api/annotation?root=bench0&name=a HTTP/1.1",
            vec![own.as_str()],
        ),
        (own_absolute.as_str(), vec![own.as_str()]),
    ] {
        let (status, body) = ask(line, &hosts);
        let error = serde_json::from_str::<serde_json::Value>(&body)
            .ok()
            .and_then(|v| v["error"].as_str().map(str::to_string));
        match error {
            Some(e) if status == 400 && !e.is_empty() && !e.contains('\n') => {}
            _ => wrong.push(format!("{line} {hosts:?}: {status} {body}")),
        }
    }
    assert!(
        wrong.is_empty(),
        "not refused with 400:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn a_client_still_sending_an_upload_too_large_reads_why() {
    let running = Running::start(matseg_serve::ServeOptions {
        upload_mb: 5,
        ..options(Vec::new(), Vec::new())
    });
    let size = 7_235_174;
    let mut request = format!(
        "POST /api/upload?name=big.jpg HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nx-matseg-token: {}\r\ncontent-type: image/jpeg\r\ncontent-length: {size}\r\nConnection: close\r\n\r\n",
        running.address.port(),
        router::TOKEN
    )
    .into_bytes();
    request.extend(std::iter::repeat_n(0xFF, size));
    let (status, body) = raw(running.address, &request);
    assert_eq!(status, 413, "{body}");
    let error = router::error_of(body.as_bytes());
    assert!(
        error.contains("6.9 MiB (7235174 bytes)") && error.contains("5 MiB (--upload-mb)"),
        "{error}"
    );
}
