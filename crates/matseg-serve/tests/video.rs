//! The video page's API through the router (no socket): the video list, a
//! video's facts and frames, a tracking job from start to its labels and
//! archive, uploads, and every refused request (a corrupt or misnamed
//! upload, a point outside the frames, a frame past the end, an unknown
//! job), after which the server goes on answering. Videos are made and read
//! with the ffmpeg that scripts/ffmpeg-env.sh installs (`make test` runs it).

mod ffmpeg;
mod router;

use axum::http::StatusCode;
use ffmpeg::{run_ffmpeg, write_test_pattern};
use matseg_serve::{app::router, state};
use router::{error_of, get, json, options, post};
use std::time::{Duration, Instant};

#[tokio::test(flavor = "multi_thread")]
async fn a_video_is_tracked_and_its_labels_served() {
    let videos = tempfile::tempdir().unwrap();
    write_test_pattern(&videos.path().join("clip.mkv"));
    let app = router(state(&options(vec![videos.path().into()], Vec::new())).unwrap());
    for page in ["/video", "/video.js"] {
        assert_eq!(get(&app, page).await.0, StatusCode::OK, "{page}");
    }

    let (status, _, body) = get(&app, "/api/videos").await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(
        json(&body)["videos"],
        serde_json::json!([{ "root": "data0", "path": "clip.mkv" }])
    );
    let clip = "root=data0&path=clip.mkv";
    let (status, _, body) = get(&app, &format!("/api/video?{clip}")).await;
    assert_eq!(status, StatusCode::OK);
    let info = json(&body);
    assert_eq!(
        (&info["width"], &info["height"], &info["frames"]),
        (&160.into(), &120.into(), &6.into())
    );
    let (status, _, jpeg) = get(&app, &format!("/api/video/frame?{clip}&frame=5")).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(
        image::load_from_memory(&jpeg)
            .unwrap()
            .to_rgb8()
            .dimensions(),
        (160, 120)
    );

    // Refused: a frame past the end, a point outside, a file that is not a
    // video, a root that does not exist.
    let (status, _, body) = get(&app, &format!("/api/video/frame?{clip}&frame=6")).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error_of(&body),
        "frame 6: past the end: clip.mkv has 6 frames"
    );
    let (status, _, body) = post(&app, &format!("/api/track?{clip}&points=10,500"), vec![]).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error_of(&body),
        "point 10,500: outside the 160x120 frames of clip.mkv"
    );
    let (status, _, body) = post(
        &app,
        &format!("/api/track?{clip}&frame=9&points=10,10"),
        vec![],
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error_of(&body),
        "frame 9: past the end: clip.mkv has 6 frames"
    );
    let (status, _, _) = get(&app, "/api/video?root=nothing&path=clip.mkv").await;
    assert_eq!(status, StatusCode::NOT_FOUND);

    // A track: started, polled (with a deadline) until done.
    let (status, _, body) = post(
        &app,
        &format!("/api/track?{clip}&frame=2&points=20,30;140,100"),
        vec![],
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    let job = json(&body)["job"].as_u64().unwrap();
    let started = Instant::now();
    let report = loop {
        let (status, _, body) = get(&app, &format!("/api/track?job={job}")).await;
        assert_eq!(status, StatusCode::OK);
        let answer = json(&body);
        match answer["state"].as_str().unwrap() {
            "done" => break answer["report"].clone(),
            "running" => {}
            other => panic!("the track {other}: {answer}"),
        }
        assert!(started.elapsed() < Duration::from_secs(300), "no end");
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    assert_eq!(report["frames"], 6);
    assert_eq!(report["clicked_frame"], 2);
    assert_eq!(report["areas"].as_array().unwrap().len(), 6);

    // Its frames and labels, one a frame; the clicked points carry their
    // own labels on the clicked frame.
    for frame in 0..6 {
        let (status, _, jpeg) =
            get(&app, &format!("/api/track/frame?job={job}&frame={frame}")).await;
        assert_eq!(status, StatusCode::OK);
        assert!(image::load_from_memory(&jpeg).is_ok());
        let (status, _, png) = get(
            &app,
            &format!("/api/track/frame?job={job}&frame={frame}&part=labels"),
        )
        .await;
        assert_eq!(status, StatusCode::OK);
        let labels = image::load_from_memory(&png).unwrap().to_luma8();
        assert_eq!(labels.dimensions(), (160, 120));
        if frame == 2 {
            assert_eq!(
                (labels.get_pixel(20, 30).0, labels.get_pixel(140, 100).0),
                ([1], [2])
            );
        }
    }
    let (status, _, _) = get(
        &app,
        &format!("/api/track/frame?job={job}&frame=6&part=labels"),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND);

    // The archive: track.json and the six label PNGs, as served.
    let (status, _, tar) = get(&app, &format!("/api/track/download?job={job}")).await;
    assert_eq!(status, StatusCode::OK);
    let mut archive = tar::Archive::new(std::io::Cursor::new(tar));
    let names: Vec<String> = archive
        .entries()
        .unwrap()
        .map(|e| e.unwrap().path().unwrap().display().to_string())
        .collect();
    let expected: Vec<String> = std::iter::once("track.json".to_string())
        .chain((0..6).map(|i| format!("labels/{i:06}.png")))
        .collect();
    assert_eq!(names, expected);
    let (status, _, overlay) = get(&app, &format!("/api/track/overlay?job={job}")).await;
    assert_eq!(status, StatusCode::OK);
    assert!(!overlay.is_empty());

    let (status, _, body) = get(&app, "/api/track?job=999").await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert!(error_of(&body).starts_with("track job 999: no such job"));

    // Uploads: a corrupt video and a file name that is not a video's are
    // refused and nothing is kept; a real one is listed and opens.
    let (status, _, body) = post(
        &app,
        "/api/video/upload?name=broken.mp4",
        b"not a video".to_vec(),
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(
        error_of(&body).starts_with("broken.mp4: not a readable video"),
        "{}",
        error_of(&body)
    );
    // A video whose stream has no frame is no video to click on.
    let empty = videos.path().join("empty.avi");
    run_ffmpeg([
        "-f",
        "lavfi",
        "-i",
        "testsrc=size=64x48:rate=10",
        "-t",
        "0",
        "-c:v",
        "libx264",
        empty.to_str().unwrap(),
    ]);
    let (status, _, body) = post(
        &app,
        "/api/video/upload?name=empty.avi",
        std::fs::read(&empty).unwrap(),
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert_eq!(
        error_of(&body),
        "empty.avi: not a video: its video stream has no frames"
    );
    let bytes = std::fs::read(videos.path().join("clip.mkv")).unwrap();
    let (status, _, body) = post(&app, "/api/video/upload?name=notes.txt", bytes.clone()).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(error_of(&body).starts_with("upload name \"notes.txt\""));
    let (status, _, body) = post(&app, "/api/video/upload?name=mine.mkv", bytes).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(json(&body)["frames"], 6);
    let (_, _, body) = get(&app, "/api/videos").await;
    assert_eq!(
        json(&body)["videos"],
        serde_json::json!([
            { "root": "data0", "path": "clip.mkv" },
            { "root": "upload", "path": "mine.mkv" }
        ])
    );
    let (status, _, _) = get(&app, "/api/video/frame?root=upload&path=mine.mkv&frame=0").await;
    assert_eq!(status, StatusCode::OK);
}
