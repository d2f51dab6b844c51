//! The pages that work on folders, through the router on the shipped
//! model: browsing datasets (sample folders and shards), annotating a point
//! benchmark (saved files read back by the evaluation reader) and
//! evaluating it (the same scores as the evaluation library).

mod router;

use axum::http::StatusCode;
use matseg_eval::Annotation;
use matseg_serve::{app::router, state};
use router::{get, json, options, post, sample};
use std::path::Path;
use std::time::{Duration, Instant};

async fn get_json(app: &axum::Router, uri: &str) -> serde_json::Value {
    let (status, _, body) = get(app, uri).await;
    assert_eq!(
        status,
        StatusCode::OK,
        "{uri}: {}",
        String::from_utf8_lossy(&body)
    );
    json(&body)
}

/// Status and JSON answer of `POST uri` with `body`.
async fn post_json(app: &axum::Router, uri: &str, body: &str) -> (StatusCode, serde_json::Value) {
    let (status, _, body) = post(app, uri, body.to_string()).await;
    (status, json(&body))
}

fn png(bytes: &[u8]) -> image::DynamicImage {
    image::load_from_memory(bytes).unwrap()
}

#[tokio::test(flavor = "multi_thread")]
async fn datasets_are_browsed_a_page_at_a_time_from_folders_and_shards() {
    let folders = tempfile::tempdir().unwrap();
    for i in 0..5 {
        matseg_data::folders::write_sample(folders.path(), &sample(i)).unwrap();
    }
    let shards = tempfile::tempdir().unwrap();
    let mut writer =
        matseg_data::wds::ShardWriter::create(matseg_data::wds::shard_path(shards.path(), 0))
            .unwrap();
    for i in 0..3 {
        writer.append(&sample(i)).unwrap();
    }
    writer.finish().unwrap();
    let app = router(
        state(&options(
            vec![folders.path().into(), shards.path().into()],
            vec![],
        ))
        .unwrap(),
    );

    let datasets = get_json(&app, "/api/datasets").await;
    let sizes: Vec<u64> = datasets["datasets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["samples"].as_u64().unwrap())
        .collect();
    assert_eq!(sizes, [5, 3]);
    let photos = get_json(&app, "/api/photos").await;
    assert!(
        photos["photos"]
            .as_array()
            .unwrap()
            .iter()
            .all(|p| p["root"] == "photos"),
        "datasets are browsed, not listed as photos"
    );

    let page = get_json(&app, "/api/samples?root=data0&offset=2&limit=2").await;
    assert_eq!(page["total"], 5);
    let keys: Vec<&str> = page["samples"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["key"].as_str().unwrap())
        .collect();
    assert_eq!(keys, ["00000002", "00000003"]);
    let last = get_json(&app, "/api/samples?root=data0&offset=4&limit=100").await;
    assert_eq!(last["samples"].as_array().unwrap().len(), 1);

    for root in ["data0", "data1"] {
        let one = get_json(&app, &format!("/api/sample?root={root}&index=2")).await;
        assert_eq!(
            (
                one["width"].as_u64(),
                one["height"].as_u64(),
                one["masks"].as_u64()
            ),
            (Some(32), Some(24), Some(2))
        );
        assert_eq!(one["meta"]["index"], 2);
        let (status, _, mask) = get(
            &app,
            &format!("/api/sample/image?root={root}&index=2&part=mask&mask=1"),
        )
        .await;
        assert_eq!(status, StatusCode::OK);
        let mask = png(&mask).to_luma8();
        assert_eq!(mask.get_pixel(0, 0).0[0], 255);
        assert_eq!(
            mask.get_pixel(31, 23).0[0],
            255 - 31 * 8,
            "masks come back losslessly"
        );
        for part in ["image", "thumbnail", "roi", "annotation", "overlay"] {
            let (status, _, bytes) = get(
                &app,
                &format!("/api/sample/image?root={root}&index=2&part={part}"),
            )
            .await;
            assert_eq!(status, StatusCode::OK, "{part}");
            assert_eq!(png(&bytes).width(), 32, "{part}");
        }
        // The annotation: material 0's colour where mask 0 is full, 1's
        // where mask 1 is.
        let (_, _, bytes) = get(
            &app,
            &format!("/api/sample/image?root={root}&index=2&part=annotation"),
        )
        .await;
        let annotation = png(&bytes).to_rgb8();
        assert_eq!(annotation.get_pixel(0, 5).0, matseg_scene::PALETTE[1]);
        // A sample opens on the segment page by index.
        let (status, _, _) = get(
            &app,
            &format!("/api/similarity?root={root}&path=sample/2&points=3,3"),
        )
        .await;
        assert_eq!(status, StatusCode::OK);
    }
    let (status, _, _) = get(&app, "/api/sample?root=data0&index=5").await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    let (status, _, _) = get(
        &app,
        "/api/sample/image?root=data0&index=0&part=mask&mask=2",
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    let (status, _, _) = get(&app, "/api/sample/image?root=data0&index=0&part=nothing").await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    let (status, _, _) = get(&app, "/api/samples?root=photos").await;
    assert_eq!(status, StatusCode::NOT_FOUND);
}

/// A benchmark folder with two bundled photos and no annotation.
fn bench_folder() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("images")).unwrap();
    for name in ["coffee.jpg", "chelsea.jpg"] {
        std::fs::copy(
            matseg_pipeline::sources::assets_dir()
                .join("photos")
                .join(name),
            dir.path().join("images").join(name),
        )
        .unwrap();
    }
    dir
}

const COFFEE: &str = r#"{"groups": [
    {"id": "1", "name": "coffee", "points": [[290, 130, 5], [300, 140, 5]]},
    {"id": "2", "name": "table", "points": [[540, 80, 5], [560, 350, 5]]},
    {"id": "3", "name": "", "points": [[150, 300, 5]]}],
  "relations": [{"ids": ["1", "3"], "weight": 0.6}]}"#;
const CHELSEA: &str = r#"{"groups": [
    {"id": "1", "name": "fur", "points": [[200, 150, 5], [250, 200, 5]]},
    {"id": "2", "name": "wall", "points": [[20, 20, 5]]}]}"#;

/// `to` relative to the working folder (`../..` as far as needed).
fn relative_to_here(to: &Path) -> std::path::PathBuf {
    let here = std::env::current_dir().unwrap().canonicalize().unwrap();
    let to = to.canonicalize().unwrap();
    let common = here
        .components()
        .zip(to.components())
        .take_while(|(a, b)| a == b)
        .count();
    let mut relative = std::path::PathBuf::new();
    for _ in here.components().skip(common) {
        relative.push("..");
    }
    relative.extend(to.components().skip(common));
    relative
}

#[tokio::test(flavor = "multi_thread")]
async fn a_benchmark_named_by_a_relative_path_opens_as_an_absolute_one() {
    let bench = bench_folder();
    let relative = relative_to_here(bench.path());
    assert!(relative.is_relative());
    let mut answers = Vec::new();
    for root in [relative, bench.path().to_path_buf()] {
        let app = router(state(&options(vec![], vec![root.clone()])).unwrap());
        let listing = get_json(&app, "/api/benches").await;
        let image = listing["benches"][0]["images"][0].clone();
        let saved = get_json(&app, "/api/annotation?root=bench0&name=chelsea").await;
        for path in [&image["path"], &saved["path"]] {
            assert_eq!(path, "images/chelsea.jpg", "{}", root.display());
            let uri = format!("/api/photo?root=bench0&path={}", path.as_str().unwrap());
            assert_eq!(
                get(&app, &uri).await.0,
                StatusCode::OK,
                "{}",
                root.display()
            );
        }
        answers.push((listing, saved));
    }
    assert_eq!(
        answers[0], answers[1],
        "the same answers, whichever way it was named"
    );
}

#[tokio::test(flavor = "multi_thread")]
async fn annotations_are_saved_in_the_benchmark_layout_and_evaluated() {
    let bench = bench_folder();
    let app = router(state(&options(vec![], vec![bench.path().into()])).unwrap());
    let listing = get_json(&app, "/api/benches").await;
    let images = &listing["benches"][0]["images"];
    assert_eq!(images.as_array().unwrap().len(), 2);
    assert_eq!(images[0]["groups"], 0);
    assert!(listing["baselines"]
        .as_array()
        .unwrap()
        .contains(&"rgb".into()));

    let (status, saved) = post_json(&app, "/api/annotation?root=bench0&name=coffee", COFFEE).await;
    assert_eq!(status, StatusCode::OK, "{saved}");
    let (status, _) = post_json(&app, "/api/annotation?root=bench0&name=chelsea", CHELSEA).await;
    assert_eq!(status, StatusCode::OK);
    let data = bench.path().join("data");
    assert_eq!(
        std::fs::read_to_string(data.join("coffee/group_relations.txt")).unwrap(),
        "[1, 3]\n"
    );
    assert!(!data.join("chelsea/group_relations.txt").exists());

    // What the page reopens is what it saved.
    let reopened = get_json(&app, "/api/annotation?root=bench0&name=coffee").await;
    let sent: Annotation = serde_json::from_str(COFFEE).unwrap();
    assert_eq!(
        serde_json::from_value::<Annotation>(reopened.clone()).unwrap(),
        sent
    );
    assert_eq!(
        (reopened["width"].as_u64(), reopened["height"].as_u64()),
        (Some(600), Some(400))
    );

    // The evaluation reader parses the files: the library's annotation
    // reader gives back what was sent, and the benchmark loads.
    assert_eq!(Annotation::read(&data.join("coffee")).unwrap(), Some(sent));
    let loaded = matseg_eval::load_point_benchmark(bench.path(), false).unwrap();
    assert_eq!(loaded.images.len(), 2);
    let coffee = &loaded.images[1];
    assert_eq!(coffee.name, "coffee");
    assert_eq!(
        coffee.points.iter().map(Vec::len).collect::<Vec<_>>(),
        [2, 2, 1]
    );
    assert_eq!(coffee.weights[0][2], matseg_eval::points::SQUARE_RELATION);
    assert!(coffee.has_relations && !loaded.images[0].has_relations);

    // Refused edits leave the saved files as they were.
    let before = std::fs::read(data.join("coffee/data.json")).unwrap();
    for (body, problem) in [
        ("{\"groups\": [", "malformed JSON"),
        (
            r#"{"groups": [{"id": "1", "points": [[600, 10, 5]]}]}"#,
            "outside the 600x400 image",
        ),
        (
            r#"{"groups": [{"id": "1", "points": [[6, 10, 5]]}], "relations": [{"ids": ["1", "4"], "weight": 0.3}]}"#,
            "group 4 unknown",
        ),
    ] {
        let (status, error) =
            post_json(&app, "/api/annotation?root=bench0&name=coffee", body).await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{body}");
        assert!(
            error["error"].as_str().unwrap().contains(problem),
            "{error}"
        );
    }
    assert_eq!(
        std::fs::read(data.join("coffee/data.json")).unwrap(),
        before
    );
    // The same problem in a file written by hand: `matseg eval` refuses it
    // with the page's message.
    let (_, refused) = post_json(
        &app,
        "/api/annotation?root=bench0&name=chelsea",
        r#"{"groups": [{"id": "1", "points": [[6, 300, 5]]}]}"#,
    )
    .await;
    let hand = bench_folder();
    let chelsea = hand.path().join("data/chelsea");
    std::fs::create_dir_all(&chelsea).unwrap();
    std::fs::write(
        chelsea.join("data.json"),
        r#"{"1": {"pt_im": [[6, 300, 5]]}}"#,
    )
    .unwrap();
    let read = matseg_eval::load_point_benchmark(hand.path(), false)
        .unwrap_err()
        .to_string();
    let problem = "group 1: point (6, 300, r 5) is outside the 451x300 image";
    assert_eq!(
        refused["error"],
        format!("annotation of \"chelsea\": {problem}")
    );
    assert_eq!(
        read,
        format!("{}: {problem}", chelsea.join("data.json").display())
    );
    for (name, refused) in [
        ("../coffee", StatusCode::FORBIDDEN),
        ("nothing", StatusCode::NOT_FOUND),
    ] {
        let (status, _) = post_json(
            &app,
            &format!("/api/annotation?root=bench0&name={name}"),
            COFFEE,
        )
        .await;
        assert_eq!(status, refused, "{name}");
    }

    // Evaluate: the model and the rgb baseline, scored as the library does.
    let (status, error) = post_json(&app, "/api/evaluate?root=bench0&baselines=rgb,nope", "").await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(error["error"]
        .as_str()
        .unwrap()
        .starts_with("baseline \"nope\""));
    let (status, _) = post_json(&app, "/api/evaluate?root=bench0&baselines=rgb", "").await;
    assert_eq!(status, StatusCode::OK);
    let started = Instant::now();
    let report = loop {
        let answer = get_json(&app, "/api/evaluate?root=bench0").await;
        match answer["state"].as_str().unwrap() {
            "running" => tokio::time::sleep(Duration::from_millis(200)).await,
            "done" => break answer["report"].clone(),
            other => panic!("{other}: {answer}"),
        }
        assert!(started.elapsed() < Duration::from_secs(600), "no end");
    };
    let models = report["models"].as_array().unwrap();
    assert_eq!(models.len(), 2);
    assert_eq!(models[0]["model"], "rgb");
    assert_eq!(models[0]["counts"]["images"], 2);
    assert_eq!(models[0]["counts"]["soft_images"], 1);
    assert_eq!(models[0]["counts"]["points"], 8);
    let rgb = matseg_eval::baselines::baseline("rgb").unwrap();
    let direct = matseg_eval::evaluate_points(
        &matseg_eval::Described(rgb),
        &loaded,
        700,
        &matseg_image::progress::Silent,
    )
    .unwrap();
    assert_eq!(
        models[0]["all_by_material"].as_f64(),
        direct.all_by_material
    );
    assert_eq!(
        models[0]["soft_by_material"].as_f64(),
        direct.soft_by_material
    );
    for model in models {
        let all = model["all_by_material"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&all), "{model}");
    }
    assert_eq!(empty_annotation_removes_it(&app, bench.path()).await, ());
}

/// Saving no groups removes an image's annotation.
async fn empty_annotation_removes_it(app: &axum::Router, bench: &Path) {
    let (status, _) = post_json(
        app,
        "/api/annotation?root=bench0&name=chelsea",
        r#"{"groups": []}"#,
    )
    .await;
    assert_eq!(status, StatusCode::OK);
    assert!(!bench.join("data/chelsea").exists());
}
