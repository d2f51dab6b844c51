//! Requests another web page open in the same browser could send (a
//! cross-site form or fetch, an image tag, a page on another domain that
//! rebinds its name to 127.0.0.1), through the router on the shipped
//! model: each refused, and the benchmark's files, the uploads and the
//! evaluations just as they were. The page's own requests still work.

mod router;

use axum::body::Body;
use axum::http::{Method, Request, StatusCode};
use matseg_serve::{app::router, state, TokenChoice};
use router::{options, send, send_as_is, HOST, TOKEN};
use std::path::Path;

/// The hand-placed annotation another page tries to replace.
const SAVED: &str =
    r#"{"1": {"pt_im": [[290, 130, 5], [300, 150, 5]]}, "2": {"pt_im": [[540, 80, 5]]}}"#;

/// What a forged request carries.
struct Forged {
    name: &'static str,
    method: Method,
    uri: &'static str,
    headers: Vec<(&'static str, &'static str)>,
    refused: StatusCode,
}

fn forged(
    name: &'static str,
    method: Method,
    uri: &'static str,
    headers: &[(&'static str, &'static str)],
    refused: StatusCode,
) -> Forged {
    Forged {
        name,
        method,
        uri,
        headers: headers.to_vec(),
        refused,
    }
}

/// The forged requests: `token` is what a page that somehow knew the
/// token would add (none when the server wants none).
fn forged_requests(token: Option<&'static str>) -> Vec<Forged> {
    use Method as M;
    use StatusCode as S;
    const ANNOTATION: &str = "/api/annotation?root=bench0&name=balance";
    let evil = [("host", "evil.example"), ("origin", "http://evil.example")];
    let own = ("host", HOST);
    let json = ("content-type", "application/json");
    let form = ("content-type", "text/plain");
    let from_elsewhere = ("origin", "http://evil.example");
    let with_token = |mut headers: Vec<(&'static str, &'static str)>| {
        if let Some(t) = token {
            headers.push(("x-matseg-token", t));
        }
        headers
    };
    let mut list = vec![
        // A cross-site form: its own Host and Origin (a rebinding page), a
        // plain body type.
        forged(
            "rebound form",
            M::POST,
            ANNOTATION,
            &[evil[0], evil[1], form],
            S::FORBIDDEN,
        ),
        forged(
            "rebound json",
            M::POST,
            ANNOTATION,
            &[evil[0], json],
            S::FORBIDDEN,
        ),
        // Reads through a rebound name.
        forged("rebound read", M::GET, ANNOTATION, &[evil[0]], S::FORBIDDEN),
        forged(
            "rebound photo",
            M::GET,
            "/api/photo?root=bench0&path=images/balance.jpg",
            &[evil[0]],
            S::FORBIDDEN,
        ),
        forged(
            "rebound page",
            M::GET,
            "/annotate",
            &[("host", "evil.example:8080")],
            S::FORBIDDEN,
        ),
        forged(
            "rebound list",
            M::GET,
            "/api/benches",
            &[("host", "localhost.evil.example")],
            S::FORBIDDEN,
        ),
    ];
    let with_own = |extra: &[(&'static str, &'static str)]| {
        let mut headers = vec![own];
        headers.extend_from_slice(extra);
        headers
    };
    for (name, method, uri, headers, refused) in [
        // Another site's fetch to the right address: its Origin.
        (
            "cross-origin save",
            M::POST,
            ANNOTATION,
            with_own(&[json, from_elsewhere]),
            S::FORBIDDEN,
        ),
        (
            "cross-origin null",
            M::POST,
            ANNOTATION,
            with_own(&[json, ("origin", "null")]),
            S::FORBIDDEN,
        ),
        (
            "cross-origin read",
            M::GET,
            ANNOTATION,
            with_own(&[from_elsewhere]),
            S::FORBIDDEN,
        ),
        (
            "cross-origin evaluate",
            M::POST,
            "/api/evaluate?root=bench0",
            with_own(&[json, from_elsewhere]),
            S::FORBIDDEN,
        ),
        (
            "cross-origin cancel",
            M::DELETE,
            "/api/evaluate?root=bench0",
            with_own(&[from_elsewhere]),
            S::FORBIDDEN,
        ),
        // An image tag or a no-cors fetch: no Origin, but the browser's mark.
        (
            "cross-site image",
            M::GET,
            "/api/photo?root=bench0&path=images/balance.jpg",
            with_own(&[("sec-fetch-site", "cross-site")]),
            S::FORBIDDEN,
        ),
        (
            "cross-site selection",
            M::GET,
            "/api/select?root=bench0&path=images/balance.jpg&positive=5,5",
            with_own(&[("sec-fetch-site", "cross-site")]),
            S::FORBIDDEN,
        ),
        (
            "cross-site save",
            M::POST,
            ANNOTATION,
            with_own(&[json, ("sec-fetch-site", "cross-site")]),
            S::FORBIDDEN,
        ),
        // Even the page's own request, with a name that leaves the
        // benchmark.
        (
            "escaping save",
            M::POST,
            "/api/annotation?root=bench0&name=..%2F..%2Fbalance",
            with_own(&[json]),
            S::FORBIDDEN,
        ),
        (
            "escaping removal",
            M::POST,
            "/api/annotation?root=bench0&name=..",
            with_own(&[json]),
            S::FORBIDDEN,
        ),
        // A body type a plain form can send.
        (
            "form save",
            M::POST,
            ANNOTATION,
            with_own(&[form]),
            S::UNSUPPORTED_MEDIA_TYPE,
        ),
        (
            "untyped save",
            M::POST,
            ANNOTATION,
            with_own(&[]),
            S::UNSUPPORTED_MEDIA_TYPE,
        ),
        (
            "form upload",
            M::POST,
            "/api/upload?name=a.png",
            with_own(&[("content-type", "multipart/form-data; boundary=x")]),
            S::UNSUPPORTED_MEDIA_TYPE,
        ),
        (
            "form evaluate",
            M::POST,
            "/api/evaluate?root=bench0",
            with_own(&[("content-type", "application/x-www-form-urlencoded")]),
            S::UNSUPPORTED_MEDIA_TYPE,
        ),
    ] {
        list.push(Forged {
            name,
            method,
            uri,
            headers: with_token(headers),
            refused,
        });
    }
    list
}

/// A request with exactly `headers`, and `body` for a POST.
fn request(method: Method, uri: &str, headers: &[(&str, &str)], body: &str) -> Request<Body> {
    let mut request = Request::builder().method(method).uri(uri);
    for (name, value) in headers {
        request = request.header(*name, *value);
    }
    request.body(Body::from(body.to_string())).unwrap()
}

/// A benchmark of one photo with a saved annotation.
fn bench() -> tempfile::TempDir {
    let bench = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(bench.path().join("images")).unwrap();
    std::fs::create_dir_all(bench.path().join("data/balance")).unwrap();
    let photos = matseg_pipeline::sources::assets_dir().join("photos");
    std::fs::copy(
        photos.join("coffee.jpg"),
        bench.path().join("images/balance.jpg"),
    )
    .unwrap();
    std::fs::write(bench.path().join("data/balance/data.json"), SAVED).unwrap();
    bench
}

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files.extend(snapshot(&path));
        } else {
            files.push((path.display().to_string(), std::fs::read(&path).unwrap()));
        }
    }
    files.sort();
    files
}

async fn forged_requests_change_nothing(token: TokenChoice, carried: Option<&'static str>) {
    let bench = bench();
    let app_state = state(&matseg_serve::ServeOptions {
        token,
        ..options(Vec::new(), vec![bench.path().to_path_buf()])
    })
    .unwrap();
    let app = router(app_state.clone());
    let before = snapshot(bench.path());
    let attack = r#"{"groups": [{"id": "1", "points": [[1, 1, 5]]}], "relations": []}"#;
    for forged in forged_requests(carried) {
        let (status, kind, body) = send_as_is(
            &app,
            request(forged.method.clone(), forged.uri, &forged.headers, attack),
        )
        .await;
        assert_eq!(
            status,
            forged.refused,
            "{}: {}",
            forged.name,
            String::from_utf8_lossy(&body)
        );
        assert_eq!(kind, "application/json", "{}", forged.name);
        let error = router::error_of(&body);
        assert!(
            !error.contains("pt_im") && !error.contains('\n'),
            "{}: {error}",
            forged.name
        );
    }
    assert_eq!(
        snapshot(bench.path()),
        before,
        "the benchmark's files are as they were"
    );
    assert_eq!(
        snapshot(app_state.folder.path()),
        Vec::new(),
        "nothing uploaded"
    );
    let (_, _, evaluation) = router::get(&app, "/api/evaluate?root=bench0").await;
    assert_eq!(
        router::json(&evaluation)["state"],
        "idle",
        "no evaluation started"
    );

    // A CORS preflight is never granted.
    let (status, _, _) = send_as_is(
        &app,
        request(
            Method::OPTIONS,
            "/api/annotation?root=bench0&name=balance",
            &[
                ("host", HOST),
                ("origin", "http://evil.example"),
                ("access-control-request-method", "POST"),
            ],
            "",
        ),
    )
    .await;
    assert!(!status.is_success(), "{status}");

    // The page's own save still works.
    let own = request(
        Method::POST,
        "/api/annotation?root=bench0&name=balance",
        &[
            ("host", HOST),
            ("origin", "http://127.0.0.1:8080"),
            ("content-type", "application/json"),
            ("sec-fetch-site", "same-origin"),
        ],
        attack,
    );
    let (status, _, body) = send(&app, own).await;
    assert_eq!(status, StatusCode::OK, "{}", String::from_utf8_lossy(&body));
    assert_ne!(snapshot(bench.path()), before);
}

#[tokio::test(flavor = "multi_thread")]
async fn forged_requests_are_refused_with_a_token() {
    // Even a page that knew the token is refused on Host, Origin and type.
    forged_requests_change_nothing(TokenChoice::Given(TOKEN.into()), Some(TOKEN)).await;
}

#[tokio::test(flavor = "multi_thread")]
async fn forged_requests_are_refused_without_a_token() {
    forged_requests_change_nothing(TokenChoice::Off, None).await;
}

#[tokio::test(flavor = "multi_thread")]
async fn answers_keep_the_pages_out_of_other_pages_frames() {
    let app = router(state(&options(Vec::new(), Vec::new())).unwrap());
    let response = {
        use tower::ServiceExt;
        app.oneshot(request(Method::GET, "/", &[("host", HOST)], ""))
            .await
            .unwrap()
    };
    let headers = response.headers();
    assert_eq!(headers["x-frame-options"], "DENY");
    assert_eq!(headers["content-security-policy"], "frame-ancestors 'none'");
    assert_eq!(headers["referrer-policy"], "no-referrer");
    assert_eq!(headers["x-content-type-options"], "nosniff");
    assert!(headers.get("access-control-allow-origin").is_none());
}
