//! Every page of `matseg serve` in a real (headless) Chromium, driven over
//! the DevTools protocol: open a bundled photo, click, and the overlay
//! appears where the material is; the map and overlay downloaded as PNG
//! files; the automatic split and an upload; browse a generated dataset
//! and open a sample; annotate two groups, save, and the files parse with
//! the evaluation reader; evaluate the benchmark and open an image's maps;
//! click a material on a video's first frame (and one none may take,
//! undone and redone), track it, and its overlay moves with it; its labels
//! downloaded; a corrupt video refused; no page wider than the window. And
//! the segment page's refinement: a negative click shrinks the selection,
//! undo, redo, removal and Esc restore exactly what was, the outline and
//! greyed views, the automatic split's legend, a tall photo fitting the
//! window. And on every page at 1280 x 800, the status bar in sight, after
//! an error too, and Annotate's Save with seven groups.
//!
//! With `MATSEG_SCREENSHOTS=DIR`, a screenshot of each page is written
//! there (a relative DIR from the workspace's root; docs/images holds the
//! ones the README shows).

mod cdp;
mod ffmpeg;

use cdp::{Browser, ALT, CTRL, SHIFT};
use ffmpeg::run_ffmpeg;
use matseg_data::{generate_dataset, GenerateOptions};
use matseg_image::progress::Silent;
use matseg_image::LicenceFilter;
use matseg_pipeline::sources::{assets_dir, Defaults, Libraries};
use matseg_scene::{Recipe2d, PALETTE};
use matseg_serve::load::{Connection, ServerAddress};
use matseg_serve::{serve_until, ServeOptions};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};

/// A started server: where it is and its token; stopped when dropped.
struct Served {
    /// `http://127.0.0.1:PORT`.
    base: String,
    address: ServerAddress,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Served {
    /// The address of a page (`/browse`, `/?root=...`), with the token
    /// the printed address carries.
    fn page(&self, path: &str) -> String {
        let join = if path.contains('?') { '&' } else { '?' };
        let token = self.address.token.as_deref().unwrap();
        format!("{}{path}{join}token={token}", self.base)
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// Starts the server on a free port, with a token of its own.
fn start_server(data: Vec<PathBuf>, bench: PathBuf) -> Served {
    let options = ServeOptions {
        data,
        bench: vec![bench],
        port: 0,
        cache_mb: 256,
        ..ServeOptions::default()
    };
    let (ready, started) = std::sync::mpsc::channel();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let thread = std::thread::spawn(move || {
        let until = |_| async move {
            let _ = stopped.await;
        };
        serve_until(&options, |r| ready.send(r.clone()).unwrap(), until).unwrap();
    });
    let started = started.recv().unwrap();
    assert!(started
        .url
        .ends_with(&format!("/?token={}", started.token.clone().unwrap())));
    Served {
        base: format!("http://{}", started.address),
        address: ServerAddress {
            host: started.address.to_string(),
            token: started.token,
        },
        stop: Some(stop),
        thread: Some(thread),
    }
}

/// Writes the page's screenshot as `serve-NAME.jpg` when asked to.
fn screenshot(browser: &mut Browser, name: &str) {
    // The controls from their top, however a click scrolled them.
    browser.eval("document.querySelector('aside')?.scrollTo(0, 0)");
    let shot = browser.screenshot();
    assert!(image::load_from_memory(&shot).is_ok(), "a JPEG screenshot");
    if let Some(dir) = std::env::var_os("MATSEG_SCREENSHOTS") {
        // A relative folder is taken from the workspace's root.
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        std::fs::write(root.join(dir).join(format!("serve-{name}.jpg")), shot).unwrap();
    }
}

/// Asserts that the page shown fits a window of its width: nothing
/// scrolls sideways.
fn assert_fits_the_window(browser: &mut Browser, page: &str) {
    let widths = browser
        .eval("[document.scrollingElement.scrollWidth, document.scrollingElement.clientWidth]");
    let (scroll, client) = (widths[0].as_u64().unwrap(), widths[1].as_u64().unwrap());
    assert!(
        scroll <= client,
        "{page}: {scroll} px wide in a window of {client}"
    );
}

/// Asserts that the page's status says something and is in sight: its box
/// lies within the window and nothing covers it.
fn assert_status_in_sight(browser: &mut Browser, page: &str) {
    assert_in_sight(browser, "#status", page);
    let text = browser.eval("document.getElementById('status').textContent");
    assert!(
        !text.as_str().unwrap().is_empty(),
        "{page}: the status is empty"
    );
}

/// Asserts that the element `selector` finds lies within the window and
/// is the element shown at its middle.
fn assert_in_sight(browser: &mut Browser, selector: &str, page: &str) {
    let seen = browser.eval(&format!(
        "(() => {{ const e = document.querySelector({selector:?}); const b = e.getBoundingClientRect();
           const top = document.elementFromPoint(b.left + b.width / 2, b.top + b.height / 2);
           return {{ box: [b.left, b.top, b.right, b.bottom], window: [innerWidth, innerHeight],
                    shown: b.width > 0 && b.height > 0 && e.contains(top) }}; }})()"
    ));
    let number = |v: &serde_json::Value| v.as_f64().unwrap();
    let [left, top, right, bottom] = [0, 1, 2, 3].map(|i| number(&seen["box"][i]));
    let (width, height) = (number(&seen["window"][0]), number(&seen["window"][1]));
    assert!(
        left >= 0.0 && top >= 0.0 && right <= width && bottom <= height,
        "{page}: {selector} at {left},{top}-{right},{bottom} in a window of {width} x {height}"
    );
    assert_eq!(seen["shown"], true, "{page}: {selector} is covered");
}

/// Asserts that the status says an error that says `said`, in sight.
fn assert_error_in_sight(browser: &mut Browser, said: &str, page: &str) {
    browser.wait_for(&format!(
        "document.getElementById('status').textContent.includes({said:?})"
    ));
    assert_eq!(
        browser.eval("document.getElementById('status').classList.contains('error')"),
        true,
        "{page}: shown as an error"
    );
    assert_status_in_sight(browser, page);
}

/// The body of `GET path` from the server (a plain HTTP/1.1 request).
fn http_get(server: &Served, path: &str) -> Vec<u8> {
    let mut connection = Connection::open(&server.address).unwrap();
    let (answer, body) = connection.get_body(path).unwrap();
    assert_eq!(answer.status, 200, "{path}");
    body
}

/// `base` blended 70% towards `colour`, as the pages draw a label.
fn blended(base: [i32; 3], colour: [u8; 3]) -> [i32; 3] {
    [0, 1, 2].map(|c| (base[c] as f64 * 0.3 + colour[c] as f64 * 0.7).round() as i32)
}

fn close(a: [i32; 3], b: [i32; 3], tolerance: i32) -> bool {
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= tolerance)
}

#[test]
fn every_page_works_in_a_real_browser() {
    let data = tempfile::tempdir().unwrap();
    let libraries = Libraries::load(
        &[],
        &[],
        256,
        Defaults::Bundled,
        &LicenceFilter::parse("").unwrap(),
    )
    .unwrap();
    let scenes = GenerateOptions::folders(data.path(), 12, 0);
    generate_dataset(&scenes, &Recipe2d::default(), libraries.sources(), &Silent).unwrap();
    let bench = tempfile::tempdir().unwrap();
    std::fs::create_dir(bench.path().join("images")).unwrap();
    for name in ["coffee.jpg", "chelsea.jpg"] {
        std::fs::copy(
            assets_dir().join("photos").join(name),
            bench.path().join("images").join(name),
        )
        .unwrap();
    }
    let videos = tempfile::tempdir().unwrap();
    write_moving_patch_video(&videos.path().join("clip.mkv"));
    let server = start_server(
        vec![data.path().into(), videos.path().into()],
        bench.path().into(),
    );
    let mut browser = Browser::start(1280, 800);

    without_the_token(&mut browser, &server);
    segment_page(&mut browser, &server);
    porcelain_then_crema(&mut browser, &server);
    browse_page(&mut browser, &server);
    annotate_page(&mut browser, &server, bench.path());
    evaluate_page(&mut browser, &server);
    video_page(&mut browser, &server);
}

/// The moving patch's frames: its size, count, and left edge on frame `i`.
const CLIP_SIZE: (u32, u32) = (320, 240);
const CLIP_FRAMES: u32 = 12;
const PATCH: u32 = 96;
fn patch_left(i: u32) -> u32 {
    40 + i * 13
}

/// A lossless video (FFV1 in MKV) of a square of wood sliding right
/// across grass, 12 frames; the wood's grain moves with the square.
fn write_moving_patch_video(file: &Path) {
    let textures = assets_dir().join("textures");
    let grass = image::open(textures.join("grass.jpg")).unwrap().to_rgb8();
    let wood = image::open(textures.join("wood_table_coffee.jpg"))
        .unwrap()
        .to_rgb8();
    let frames = tempfile::tempdir().unwrap();
    for i in 0..CLIP_FRAMES {
        let (w, h) = CLIP_SIZE;
        let mut frame = image::imageops::crop_imm(&grass, 0, 0, w, h).to_image();
        let patch = image::imageops::crop_imm(&wood, 20, 20, PATCH, PATCH).to_image();
        image::imageops::replace(&mut frame, &patch, patch_left(i) as i64, 72);
        frame
            .save(frames.path().join(format!("{i:06}.png")))
            .unwrap();
    }
    let pattern = frames.path().join("%06d.png");
    let input = ["-framerate", "10", "-i"].map(OsStr::new);
    let output = ["-c:v", "ffv1"].map(OsStr::new);
    run_ffmpeg(
        input
            .into_iter()
            .chain([pattern.as_os_str()])
            .chain(output)
            .chain([file.as_os_str()]),
    );
}

/// Waits for the download `file` to be complete; its bytes.
fn downloaded(file: &Path) -> Vec<u8> {
    let started = std::time::Instant::now();
    while !file.is_file() {
        assert!(
            started.elapsed().as_secs() < 30,
            "{} not downloaded",
            file.display()
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    std::thread::sleep(std::time::Duration::from_millis(200));
    std::fs::read(file).unwrap()
}

fn video_page(browser: &mut Browser, server: &Served) {
    const CANVAS: &str = "#canvas";
    let shown =
        |frame: u32| format!("document.getElementById('canvas').dataset.frame === '{frame}'");
    browser.open(&server.page("/video?root=data1&path=clip.mkv"), &shown(0));
    let last = CLIP_FRAMES - 1;
    let centre = |i: u32| (patch_left(i) + PATCH / 2, 72 + PATCH / 2);
    let (x0, y0) = centre(0);
    let (x1, y1) = centre(last);
    let wood = browser.canvas_pixel(CANVAS, x0 + 20, y0 + 20);
    let grass = browser.canvas_pixel(CANVAS, 300, 20);

    // The wood clicked on the first frame, the grass right-clicked as a
    // material none may take (undone, redone), a stray click removed, and
    // tracked: on that frame the wood takes the first colour, the grass
    // stays as it was.
    browser.click_canvas(CANVAS, x0, y0, 0);
    browser.right_click_canvas(CANVAS, 300, 220);
    let listed = |browser: &mut Browser| {
        browser
            .eval("[...document.querySelectorAll('#points li')].map((li) => li.textContent.trim())")
    };
    let both = serde_json::json!([format!("{x0}, {y0} on frame 0"), "not: 300, 220 on frame 0"]);
    assert_eq!(listed(browser), both);
    browser.press_key("z", CTRL);
    assert_eq!(listed(browser).as_array().unwrap().len(), 1);
    browser.press_key("y", CTRL);
    assert_eq!(listed(browser), both);
    browser.click_canvas(CANVAS, 200, 200, ALT);
    assert_eq!(listed(browser).as_array().unwrap().len(), 3);
    browser.click_canvas(CANVAS, 202, 201, 0);
    assert_eq!(listed(browser), both, "a click on a mark removes it");
    browser.click("#track");
    browser.wait_for("document.getElementById('canvas').dataset.tracked !== undefined");
    let tinted = browser.canvas_pixel(CANVAS, x0 + 20, y0 + 20);
    assert!(
        close(tinted, blended(wood, PALETTE[0]), 3),
        "{wood:?} -> {tinted:?}"
    );
    let untouched = browser.canvas_pixel(CANVAS, 300, 20);
    assert!(close(untouched, grass, 3), "{grass:?} -> {untouched:?}");

    // On the last frame the tint is where the wood went, not where it was.
    browser.eval(&format!(
        "{{ const s = document.getElementById('frame'); s.value = '{last}'; s.dispatchEvent(new Event('input')) }}"
    ));
    browser.wait_for(&shown(last));
    let moved = browser.canvas_pixel(CANVAS, x1, y1);
    let left = browser.canvas_pixel(CANVAS, x0, y0);
    // The frame itself: the overlay at opacity 0.
    let set_opacity = |browser: &mut Browser, value: &str| {
        browser.eval(&format!(
            "{{ const o = document.getElementById('opacity'); o.value = '{value}'; o.dispatchEvent(new Event('input')) }}"
        ));
    };
    set_opacity(browser, "0");
    let (wood_there, grass_here) = (
        browser.canvas_pixel(CANVAS, x1, y1),
        browser.canvas_pixel(CANVAS, x0, y0),
    );
    set_opacity(browser, "0.7");
    assert!(
        close(moved, blended(wood_there, PALETTE[0]), 3),
        "the wood's new place is tinted: {wood_there:?} -> {moved:?}"
    );
    assert!(
        close(left, grass_here, 3),
        "the grass it left is not: {grass_here:?} -> {left:?}"
    );
    screenshot(browser, "video");
    assert_fits_the_window(browser, "video");

    // The labels downloaded: track.json and one PNG a frame, the served ones.
    let downloads = tempfile::tempdir().unwrap();
    browser.download_into(downloads.path());
    browser.click("#save-labels");
    let tar = downloaded(&downloads.path().join("clip-labels.tar"));
    let mut archive = tar::Archive::new(std::io::Cursor::new(tar));
    let mut names = Vec::new();
    let mut last_labels = Vec::new();
    for entry in archive.entries().unwrap() {
        let mut entry = entry.unwrap();
        let name = entry.path().unwrap().display().to_string();
        if name == format!("labels/{last:06}.png") {
            std::io::Read::read_to_end(&mut entry, &mut last_labels).unwrap();
        }
        if name == "track.json" {
            let report: serde_json::Value = serde_json::from_reader(&mut entry).unwrap();
            assert_eq!(report["negatives"], serde_json::json!([[300.0, 220.0]]));
        }
        names.push(name);
    }
    assert_eq!(names.len(), 1 + CLIP_FRAMES as usize, "{names:?}");
    assert_eq!(names[0], "track.json");
    let job = browser.eval("document.getElementById('canvas').dataset.tracked");
    let served = http_get(
        server,
        &format!(
            "/api/track/frame?job={}&frame={last}&part=labels",
            job.as_str().unwrap()
        ),
    );
    assert_eq!(last_labels, served);
    let labels = image::load_from_memory(&served).unwrap().to_luma8();
    assert_eq!(
        labels.get_pixel(x1, y1).0,
        [1],
        "labelled as the clicked material"
    );
    assert_eq!(
        labels.get_pixel(x0, y0).0,
        [0],
        "the grass is no clicked material"
    );
    // The shown frame's labels as a picture: the wood in its colour, the
    // grass black.
    browser.click("#save-frame-colours");
    let picture = downloaded(
        &downloads
            .path()
            .join(format!("clip-labels-{last:06}-colours.png")),
    );
    let picture = image::load_from_memory(&picture).unwrap().to_rgba8();
    assert_eq!(picture.dimensions(), labels.dimensions());
    assert_eq!(
        picture.get_pixel(x1, y1).0,
        [PALETTE[0][0], PALETTE[0][1], PALETTE[0][2], 255]
    );
    assert_eq!(picture.get_pixel(x0, y0).0, [0, 0, 0, 255]);
    assert_status_in_sight(browser, "video");

    // A corrupt video: refused in one line, and the server goes on.
    let broken = downloads.path().join("broken.mp4");
    std::fs::write(&broken, b"not a video at all").unwrap();
    browser.pick_files("#file", &[&broken]);
    assert_error_in_sight(browser, "broken.mp4: not a readable video", "video");
    assert!(http_get(server, "/api/videos").starts_with(b"{"));
}

/// A page opened without the token (a fresh browser, the bare address)
/// says what to do, takes the printed address and goes on; a wrong token
/// in the address does not hide the kept one.
fn without_the_token(browser: &mut Browser, server: &Served) {
    browser.open(
        &format!("{}/evaluate", server.base),
        "document.getElementById('access') !== null",
    );
    let said = browser.eval("document.querySelector('#access p').textContent");
    assert!(
        said.as_str()
            .unwrap()
            .contains("open the address `matseg serve` printed"),
        "{said}"
    );
    assert_in_sight(browser, "#access", "evaluate");
    // Another site's link cannot plant a token: one the server refuses is
    // not kept.
    browser.open(
        &format!("{}/evaluate?token=planted", server.base),
        "document.getElementById('access') !== null",
    );
    assert_eq!(
        browser.eval("localStorage.getItem('matseg-token')"),
        serde_json::Value::Null
    );
    // The printed address given: the page goes on by itself (the refused
    // calls repeated) and the banner leaves.
    browser.eval(&format!(
        "document.querySelector('#access input').value = {:?}",
        server.page("/")
    ));
    browser.click("#access button");
    let loaded = "document.querySelectorAll('#baselines input').length > 0";
    browser.wait_for(&format!(
        "{loaded} && document.getElementById('access') === null"
    ));
    let kept = browser.eval("localStorage.getItem('matseg-token')");
    assert_eq!(kept.as_str(), server.address.token.as_deref());
    // A wrong token in the address (an old run's link) does not hide the
    // kept one, which works.
    browser.open(
        &format!("{}/evaluate?token=an-old-runs-token", server.base),
        loaded,
    );
    assert_eq!(
        browser.eval("document.getElementById('access')"),
        serde_json::Value::Null
    );
    assert_eq!(browser.eval("localStorage.getItem('matseg-token')"), kept);
    browser.open(&format!("{}/evaluate", server.base), loaded);
    assert_eq!(
        browser.eval("document.getElementById('access')"),
        serde_json::Value::Null
    );
}

/// On the bundled coffee photo, a click on the cup's white porcelain and
/// then one on the crema select both materials, and hardly any of the
/// wooden table (`tests/masks/coffee-table.png`, drawn by hand: the table
/// beyond the saucer): two positive materials select each of them, not
/// what lies between them.
fn porcelain_then_crema(browser: &mut Browser, server: &Served) {
    const CANVAS: &str = "#canvas";
    browser.open(
        &server.page("/?root=photos&path=coffee.jpg"),
        "document.getElementById('canvas').dataset.photo === 'photos/coffee.jpg'",
    );
    let (porcelain, crema) = ((290, 45), (290, 150));
    browser.click_canvas(CANVAS, porcelain.0, porcelain.1, 0);
    browser.wait_for("document.getElementById('canvas').dataset.answered === '1'");
    browser.click_canvas(CANVAS, crema.0, crema.1, 0);
    browser.wait_for("document.getElementById('canvas').dataset.answered === '2'");
    let downloads = tempfile::tempdir().unwrap();
    browser.download_into(downloads.path());
    browser.click("#save-mask");
    let mask = downloaded(&downloads.path().join("coffee-mask.png"));
    let mask = image::load_from_memory(&mask).unwrap().to_luma8();
    let table =
        image::open(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/masks/coffee-table.png"))
            .unwrap()
            .to_luma8();
    assert_eq!(mask.dimensions(), table.dimensions());
    let selected = |(x, y): (u32, u32)| mask.get_pixel(x, y).0[0] == 255;
    assert!(selected(porcelain) && selected(crema), "both materials");
    let wood: Vec<bool> = table
        .pixels()
        .zip(mask.pixels())
        .filter(|(t, _)| t.0[0] >= 128)
        .map(|(_, m)| m.0[0] == 255)
        .collect();
    let share = wood.iter().filter(|&&m| m).count() as f64 / wood.len() as f64;
    assert!(share <= 0.05, "{:.1}% of the table selected", 100.0 * share);
}

fn segment_page(browser: &mut Browser, server: &Served) {
    const CANVAS: &str = "#canvas";
    browser.open(
        &server.page("/?root=photos&path=coffee.jpg"),
        "document.getElementById('canvas').dataset.photo === 'photos/coffee.jpg'",
    );
    let coffee = browser.canvas_pixel(CANVAS, 260, 150);
    let wood = browser.canvas_pixel(CANVAS, 560, 95);

    // A click in the coffee: the coffee takes the tint, in a colour unlike
    // the red-brown photo (not red); the table's wood stays.
    browser.click_canvas(CANVAS, 290, 130, 0);
    browser.wait_for("document.getElementById('canvas').dataset.answered === '1'");
    assert_status_in_sight(browser, "segment");
    let tinted_coffee = browser.canvas_pixel(CANVAS, 260, 150);
    let change = |a: &[i32; 3], b: &[i32; 3]| (0..3).map(|k| (a[k] - b[k]).abs()).sum::<i32>();
    assert!(
        change(&coffee, &tinted_coffee) >= 60 && tinted_coffee[1] >= coffee[1] + 20,
        "{coffee:?} -> {tinted_coffee:?}"
    );
    // The brown wood may take a faint tint; far less than the coffee's.
    let tinted_wood = browser.canvas_pixel(CANVAS, 560, 95);
    assert!(
        change(&wood, &tinted_wood) * 4 < change(&coffee, &tinted_coffee),
        "the wood is another material: {wood:?} -> {tinted_wood:?}, coffee {coffee:?} -> {tinted_coffee:?}"
    );

    // The map and the overlay downloaded: the map is the server's map,
    // the overlay the canvas.
    let downloads = tempfile::tempdir().unwrap();
    browser.download_into(downloads.path());
    browser.click("#save-map");
    browser.click("#save-overlay");
    let downloaded =
        |name: &str| image::load_from_memory(&downloaded(&downloads.path().join(name))).unwrap();
    let map = downloaded("coffee-strength.png");
    assert!(
        map.to_rgba8().pixels().all(|p| p.0[3] == 255),
        "an opaque PNG an image viewer shows"
    );
    let map = map.to_luma8();
    let served = image::load_from_memory(&http_get(
        server,
        "/api/similarity?root=photos&path=coffee.jpg&points=290,130",
    ))
    .unwrap()
    .to_luma8();
    assert_eq!(map, served, "the downloaded map is the server's");
    let overlay = downloaded("coffee-overlay.png").to_rgb8();
    assert_eq!(overlay.get_pixel(260, 150).0.map(i32::from), tinted_coffee);

    // The automatic split.
    browser.click("#auto");
    browser.wait_for("document.getElementById('canvas').dataset.answered === '2'");
    let status = browser.eval("document.getElementById('status').textContent");
    assert!(
        status.as_str().unwrap().starts_with("4 materials:"),
        "{status}"
    );
    assert_fits_the_window(browser, "segment");

    // An upload through the file picker, then a click on it.
    let chelsea = assets_dir().join("photos/chelsea.jpg");
    browser.pick_files("#file", &[&chelsea]);
    browser
        .wait_for("(document.getElementById('canvas').dataset.photo || '').startsWith('upload/')");
    let (w, h) = image::image_dimensions(&chelsea).unwrap();
    assert_eq!(
        browser.eval("[canvas.width, canvas.height]"),
        serde_json::json!([w, h])
    );
    browser.click_canvas(CANVAS, w / 2, h / 2, 0);
    browser.wait_for("document.getElementById('canvas').dataset.answered === '3'");

    // A file that is not a photo: the page says why, and keeps working.
    let notes = tempfile::NamedTempFile::new().unwrap();
    std::fs::write(notes.path(), "not a photo").unwrap();
    browser.pick_files("#file", &[notes.path()]);
    browser.wait_for(
        "document.getElementById('status').textContent.endsWith('not a PNG or JPEG image')",
    );
    assert_error_in_sight(browser, "not a PNG or JPEG image", "segment");
    // The page's icon is served.
    let icon = http_get(server, "/favicon.svg");
    assert!(icon.starts_with(b"<svg"), "an SVG icon");
    assert_eq!(
        browser.eval("document.querySelector('link[rel=icon]').href"),
        format!("{}/favicon.svg", server.base)
    );
}

fn browse_page(browser: &mut Browser, server: &Served) {
    let all_loaded = |selector: &str| {
        format!("[...document.querySelectorAll('{selector}')].every((i) => i.complete && i.naturalWidth > 0)")
    };
    browser.open(
        &server.page("/browse"),
        &format!(
            "document.querySelectorAll('#grid figure').length === 12 && {}",
            all_loaded("#grid img")
        ),
    );
    browser.click("#grid figure[data-index='3']");
    browser.wait_for(&format!(
        "document.getElementById('sample').dataset.index === '3' && {}",
        all_loaded("#pictures img")
    ));
    // The image, the overlay, the annotation, one picture per mask, the ROI.
    let masks = browser.eval(
        "Number(document.getElementById('sample-title').textContent.match(/(\\d+) materials/)[1])",
    );
    let pictures = browser.eval("document.querySelectorAll('#pictures img').length");
    assert_eq!(pictures.as_u64().unwrap(), masks.as_u64().unwrap() + 4);
    let grid_shown = browser.eval("document.getElementById('grid').offsetParent !== null");
    assert_eq!(grid_shown, false, "the sample replaces the grid");
    let sidecar = browser.eval("document.getElementById('meta').textContent");
    assert!(sidecar.as_str().unwrap().contains("\"seed\""), "{sidecar}");
    screenshot(browser, "browse");
    assert_fits_the_window(browser, "browse");
    assert_status_in_sight(browser, "browse");
    // A sample number out of range: said so, the sample shown kept.
    browser.eval(
        "{ const g = document.getElementById('goto'); g.value = '12'; g.dispatchEvent(new Event('change')) }",
    );
    assert_error_in_sight(
        browser,
        "Sample 12: no such sample; this dataset's are numbered 0 to 11.",
        "browse",
    );
    assert_eq!(
        browser.eval("document.getElementById('sample').dataset.index"),
        "3"
    );
}

fn annotate_page(browser: &mut Browser, server: &Served, bench: &Path) {
    const CANVAS: &str = "#canvas";
    let image_is =
        |name: &str| format!("document.getElementById('canvas').dataset.image === '{name}'");
    browser.open(&server.page("/annotate"), &image_is("chelsea"));
    browser.click("#images li[data-name='coffee']");
    browser.wait_for(&image_is("coffee"));
    // Group 1: the coffee; group 2: the wood; a stray point undone, another
    // removed with alt-click.
    browser.click_canvas(CANVAS, 290, 130, 0);
    browser.click_canvas(CANVAS, 300, 150, 0);
    browser.click("#new-group");
    browser.click_canvas(CANVAS, 540, 80, 0);
    browser.click_canvas(CANVAS, 560, 350, 0);
    browser.click_canvas(CANVAS, 100, 100, 0);
    browser.click("#undo");
    browser.click_canvas(CANVAS, 120, 300, 0);
    browser.click_canvas(CANVAS, 122, 303, ALT);
    // Names typed one after the other: the first kept when the second
    // field is clicked.
    browser.click("#groups li:nth-child(1) .name");
    browser.type_text("coffee");
    browser.click("#groups li:nth-child(2) .name");
    browser.type_text("wood");
    browser.click("#groups li:nth-child(1) .pick");
    browser.click("#groups li:nth-child(2) .pick");
    let names = browser.eval("[...document.querySelectorAll('#groups .name')].map((n) => n.value)");
    assert_eq!(names, serde_json::json!(["coffee", "wood"]));
    // Another image with points unsaved: asked first; Cancel stays.
    browser.accept_dialogs = false;
    browser.click("#images li[data-name='chelsea']");
    assert_eq!(browser.dialogs.len(), 1, "{:?}", browser.dialogs);
    assert!(
        browser.dialogs[0].contains("not saved"),
        "{:?}",
        browser.dialogs
    );
    assert_eq!(
        browser.eval("document.getElementById('canvas').dataset.image"),
        "coffee"
    );
    browser.accept_dialogs = true;
    browser.click("#relate-round");
    browser.click("#save");
    browser.wait_for("document.getElementById('canvas').dataset.saved === '1'");

    let loaded = matseg_eval::load_point_benchmark(bench, false).unwrap();
    assert_eq!(loaded.images.len(), 1);
    let coffee = &loaded.images[0];
    let points: Vec<Vec<(f32, f32)>> = coffee
        .points
        .iter()
        .map(|g| g.iter().map(|p| (p.x, p.y)).collect())
        .collect();
    assert_eq!(
        points,
        [
            vec![(290.0, 130.0), (300.0, 150.0)],
            vec![(540.0, 80.0), (560.0, 350.0)]
        ]
    );
    assert_eq!(coffee.weights[0][1], matseg_eval::points::ROUND_RELATION);
    let data: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(bench.join("data/coffee/data.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        (&data["1"]["name"], &data["2"]["name"]),
        (&"coffee".into(), &"wood".into())
    );

    // Reopened, the page shows what it saved (opened without the token:
    // the page kept it).
    browser.open(&format!("{}/annotate", server.base), &image_is("chelsea"));
    browser.click("#images li[data-name='coffee']");
    browser.wait_for(&image_is("coffee"));
    let status = browser.eval("document.getElementById('status').textContent");
    assert_eq!(status, "coffee: 2 groups, 4 points (saved)");
    assert_status_in_sight(browser, "annotate");
    screenshot(browser, "annotate");
    assert_fits_the_window(browser, "annotate");
}

fn evaluate_page(browser: &mut Browser, server: &Served) {
    browser.open(
        &server.page("/evaluate"),
        "document.querySelectorAll('#baselines input').length > 0",
    );
    // What the progress shows while it runs, each time it changes.
    browser.eval(
        "window.progressShown = [];
         new MutationObserver(() => window.progressShown.push({
             models: [...document.querySelectorAll('#models li')].map((li) => li.textContent),
             scored: document.getElementById('scored').textContent }))
           .observe(document.getElementById('progress'), { subtree: true, childList: true, characterData: true })",
    );
    browser.click("#run");
    browser.wait_for("document.getElementById('scores').dataset.done === '1'");
    assert_status_in_sight(browser, "evaluate");
    let models = browser.eval(
        "[...document.querySelectorAll('#scores tr td:first-child')].map((td) => td.textContent)",
    );
    assert_eq!(
        models,
        serde_json::json!(["rgb", "lab", "texture", "position", "default"])
    );
    // The model's images counted apart from the baselines', and its
    // images named as they are scored.
    let shown = browser.eval("window.progressShown");
    let shown = shown.as_array().unwrap();
    assert!(!shown.is_empty(), "the progress was shown while it ran");
    let listed = &shown.last().unwrap()["models"];
    assert_eq!(listed.as_array().unwrap().len(), 5, "{listed}");
    assert!(
        listed[0].as_str().unwrap().starts_with("baseline rgb: ")
            && listed[4]
                .as_str()
                .unwrap()
                .starts_with("the model default: "),
        "{listed}"
    );
    assert!(
        shown.iter().all(|s| s["models"]
            .as_array()
            .unwrap()
            .iter()
            .all(|m| m.as_str().unwrap().ends_with(" of 1 images"))),
        "one annotated image: {shown:?}"
    );
    assert!(
        shown.iter().all(|s| {
            let scored = s["scored"].as_str().unwrap();
            scored.is_empty()
                || scored.ends_with("describing the first image…")
                || scored.ends_with(" has scored: coffee")
        }),
        "{shown:?}"
    );
    // In a window too short for the tables and the image, the image the
    // page scrolls to lies whole above the status bar.
    let window = |height: u32| serde_json::json!({ "width": 1280, "height": height, "deviceScaleFactor": 1, "mobile": false });
    browser.call("Emulation.setDeviceMetricsOverride", window(500));
    browser.click("#images tr.pick");
    browser.wait_for("document.getElementById('canvas').dataset.image === 'coffee'");
    let clear = browser.eval(
        "document.getElementById('canvas').getBoundingClientRect().bottom
         <= document.querySelector('.bar').getBoundingClientRect().top + 0.5",
    );
    assert_eq!(
        clear, true,
        "evaluate: the opened image runs under the status bar"
    );
    browser.call("Emulation.setDeviceMetricsOverride", window(800));
    browser.click_canvas("#canvas", 292, 131, 0);
    browser.wait_for("document.getElementById('canvas').dataset.answered === '1'");
    assert_status_in_sight(browser, "evaluate");
    // The map in each of the segment page's views: each a picture of its
    // own; greyed, the photo under the map is grey.
    let mut pictures = vec![browser.eval(CANVAS_HASH)];
    for view in ["red", "heat", "grey"] {
        set_input(browser, "view-mode", view);
        pictures.push(browser.eval(CANVAS_HASH));
    }
    let distinct: std::collections::HashSet<String> =
        pictures.iter().map(|p| p.to_string()).collect();
    assert_eq!(distinct.len(), 4, "{pictures:?}");
    set_input(browser, "opacity", "0");
    let [r, g, b] = browser.canvas_pixel("#canvas", 560, 95);
    assert!(r == g && g == b, "grey: {r} {g} {b}");
    set_input(browser, "opacity", "0.7");
    set_input(browser, "view-mode", "solid");
    assert_eq!(browser.eval(CANVAS_HASH), pictures[0]);
    screenshot(browser, "evaluate");
    assert_fits_the_window(browser, "evaluate");
}

/// A JavaScript expression: a hash of the canvas's pixels.
const CANVAS_HASH: &str = "(() => { const c = document.getElementById('canvas');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let h = 0; for (let i = 0; i < d.length; i++) h = (Math.imul(h, 31) + d[i]) | 0; return h; })()";

/// A JavaScript expression: how many pixels of the canvas are pure white.
const WHITE_PIXELS: &str = "(() => { const c = document.getElementById('canvas');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let n = 0; for (let i = 0; i < d.length; i += 4) n += d[i] === 255 && d[i + 1] === 255 && d[i + 2] === 255; return n; })()";

/// The segment page's state after `answered` answers: the canvas's hash
/// and the number of pixels selected.
fn answer(browser: &mut Browser, answered: u32) -> (serde_json::Value, serde_json::Value) {
    browser.wait_for(&format!(
        "document.getElementById('canvas').dataset.answered === '{answered}' && !document.getElementById('view').classList.contains('busy')"
    ));
    let selected = browser.eval("Number(document.getElementById('canvas').dataset.selected)");
    (browser.eval(CANVAS_HASH), selected)
}

/// The mask the segment page downloads now (the selection shown, 255 in
/// it), read back.
fn downloaded_mask(browser: &mut Browser, name: &str) -> image::GrayImage {
    let dir = tempfile::tempdir().unwrap();
    browser.download_into(dir.path());
    browser.click("#save-mask");
    let png = downloaded(&dir.path().join(name));
    image::load_from_memory(&png).unwrap().to_luma8()
}

/// Sets a select or range input of the page and tells the page.
fn set_input(browser: &mut Browser, id: &str, value: &str) {
    browser.eval(&format!(
        "{{ const e = document.getElementById('{id}'); e.value = '{value}'; e.dispatchEvent(new Event('input')) }}"
    ));
}

#[test]
fn the_segment_page_refines_a_selection_by_clicks() {
    let bench = tempfile::tempdir().unwrap();
    std::fs::create_dir(bench.path().join("images")).unwrap();
    let server = start_server(Vec::new(), bench.path().into());
    let mut browser = Browser::start(1280, 800);
    let browser = &mut browser;
    const CANVAS: &str = "#canvas";
    browser.open(
        &server.page("/?root=photos&path=coffee.jpg"),
        "document.getElementById('canvas').dataset.described === '1'",
    );
    let photo = browser.eval(CANVAS_HASH);

    // The coffee clicked: on this photo the method also takes the red
    // saucer. Right-clicked, the saucer leaves the selection; the coffee
    // stays.
    browser.click_canvas(CANVAS, 290, 130, 0);
    let (coffee, coffee_area) = answer(browser, 1);
    let mask = downloaded_mask(browser, "coffee-mask.png");
    assert_eq!(mask.get_pixel(150, 315).0, [255], "the saucer is taken");
    assert_eq!(
        mask.pixels().filter(|p| p.0[0] == 255).count() as u64,
        coffee_area.as_u64().unwrap()
    );
    browser.right_click_canvas(CANVAS, 150, 315);
    let (refined, refined_area) = answer(browser, 2);
    let mask = downloaded_mask(browser, "coffee-mask.png");
    assert_eq!(mask.get_pixel(150, 315).0, [0], "the saucer is left out");
    assert_eq!(mask.get_pixel(290, 130).0, [255], "the coffee stays");
    assert!(
        refined_area.as_u64() < coffee_area.as_u64(),
        "{refined_area} < {coffee_area}"
    );
    screenshot(browser, "segment");
    // Saved: the clicks' descriptors, one positive and one negative.
    let saves = tempfile::tempdir().unwrap();
    browser.download_into(saves.path());
    browser.click("#save-selection");
    let saved = downloaded(&saves.path().join("coffee-selection.json"));
    let saved: matseg_query::select::SavedSelection = serde_json::from_slice(&saved).unwrap();
    assert_eq!((saved.positive.len(), saved.negative.len()), (1, 1));

    // Undo restores the one-click selection exactly, redo the refined one
    // (Ctrl+Shift+Z and Ctrl+Y alike).
    browser.press_key("z", CTRL);
    assert_eq!(answer(browser, 3), (coffee.clone(), coffee_area.clone()));
    browser.press_key("z", CTRL | SHIFT);
    assert_eq!(answer(browser, 4), (refined.clone(), refined_area.clone()));
    browser.press_key("z", CTRL);
    answer(browser, 5);
    browser.press_key("y", CTRL);
    assert_eq!(answer(browser, 6), (refined.clone(), refined_area));
    // An alt-click adds a negative too; a click on a mark removes it.
    browser.click_canvas(CANVAS, 560, 350, ALT);
    answer(browser, 7);
    assert_eq!(
        browser.eval("document.getElementById('canvas').dataset.clicks"),
        "3"
    );
    browser.click_canvas(CANVAS, 561, 352, 0);
    assert_eq!(answer(browser, 8).0, refined);
    browser.click_canvas(CANVAS, 151, 314, 0);
    assert_eq!(answer(browser, 9), (coffee.clone(), coffee_area.clone()));

    // The views: an outline (white edged in black) and the photo greyed
    // under cyan, each unlike the tint.
    set_input(browser, "view-mode", "outline");
    let outline = browser.eval(CANVAS_HASH);
    assert_ne!(outline, coffee);
    let white = |browser: &mut Browser| browser.eval(WHITE_PIXELS).as_u64().unwrap();
    let outline_white = white(browser);
    screenshot(browser, "segment-outline");
    set_input(browser, "view-mode", "grey");
    assert_ne!(browser.eval(CANVAS_HASH), coffee);
    let [r, g, b] = browser.canvas_pixel(CANVAS, 260, 150);
    assert!(
        b > r + 60 && g > r + 60,
        "cyan in the selection: {r} {g} {b}"
    );
    let [r, g, b] = browser.canvas_pixel(CANVAS, 560, 95);
    assert!(r == g && g == b, "grey out of it: {r} {g} {b}");
    screenshot(browser, "segment-grey");
    set_input(browser, "view-mode", "tint");
    assert_eq!(browser.eval(CANVAS_HASH), coffee);
    assert!(outline_white > white(browser) + 300, "the outline is drawn");
    // The threshold cuts the strength instead of the method's decision.
    set_input(browser, "threshold", "0.95");
    assert_eq!(
        browser.eval("document.getElementById('cut').value"),
        "threshold"
    );
    let strong = browser.eval("Number(document.getElementById('canvas').dataset.selected)");
    assert!(strong.as_u64() < coffee_area.as_u64());
    // The status says the share the threshold cuts, and keeps the time.
    let share = |browser: &mut Browser| {
        let said = browser.eval(
            "document.getElementById('status').textContent.match(/([\\d.]+)% of the photo selected, \\d+ ms$/)?.[1]",
        );
        said.as_str().map(|s| s.parse::<f64>().unwrap())
    };
    let strong_share = share(browser).expect("a share and a time");
    assert!(
        (strong_share - strong.as_f64().unwrap() / 2400.0).abs() < 0.051,
        "{strong_share}% for {strong} pixels"
    );
    set_input(browser, "cut", "own");
    let own_share = share(browser).expect("a share and a time");
    assert!(
        (own_share - coffee_area.as_f64().unwrap() / 2400.0).abs() < 0.051,
        "{own_share}% for {coffee_area} pixels"
    );

    // Esc clears the clicks: the photo as it was.
    browser.press_key("Escape", 0);
    browser.wait_for("document.getElementById('canvas').dataset.clicks === '0'");
    assert_eq!(browser.eval(CANVAS_HASH), photo);
    // No selection: the map's download says why there is none.
    browser.click("#save-map");
    assert_error_in_sight(browser, "No map yet", "segment");

    // The automatic split: a legend of its K materials, their shares, and
    // each one's mask.
    set_input(browser, "k", "3");
    browser.click("#auto");
    answer(browser, 10);
    let shares = browser.eval(
        "[...document.querySelectorAll('#legend li')].map((li) => Number(li.textContent.match(/([\\d.]+)%/)[1]))",
    );
    let shares: Vec<f64> = serde_json::from_value(shares).unwrap();
    assert_eq!(shares.len(), 3);
    assert!(
        (shares.iter().sum::<f64>() - 100.0).abs() < 0.2,
        "{shares:?}"
    );
    let dir = tempfile::tempdir().unwrap();
    browser.download_into(dir.path());
    browser.click("#legend li:nth-child(2) button");
    let png = downloaded(&dir.path().join("coffee-material-2.png"));
    let mask = image::load_from_memory(&png).unwrap();
    assert!(mask.to_rgba8().pixels().all(|p| p.0[3] == 255), "opaque");
    let mask = mask.to_luma8();
    assert!(mask.pixels().all(|p| matches!(p.0[0], 0 | 255)));
    let share = mask.pixels().filter(|p| p.0[0] == 255).count() as f64 / 2400.0;
    assert!(
        (share - shares[1]).abs() < 0.1,
        "{share} against {}",
        shares[1]
    );
    screenshot(browser, "segment-auto");
    assert_fits_the_window(browser, "segment");

    // A tall photo fits the window's height: nothing scrolls.
    let tall = dir.path().join("tall.png");
    image::RgbImage::from_fn(300, 1500, |x, y| {
        image::Rgb([(x % 256) as u8, (y % 256) as u8, 90])
    })
    .save(&tall)
    .unwrap();
    browser.pick_files("#file", &[&tall]);
    browser.wait_for("document.getElementById('canvas').height === 1500");
    let fits = browser.eval(
        "document.getElementById('canvas').getBoundingClientRect().bottom <= innerHeight
         && document.scrollingElement.scrollHeight <= document.scrollingElement.clientHeight",
    );
    assert_eq!(fits, true, "the photo fits the window");
}

#[test]
fn every_page_keeps_its_status_in_sight() {
    // A benchmark of one photo whose labels.json names its materials, no
    // dataset, no video.
    let bench = tempfile::tempdir().unwrap();
    std::fs::create_dir(bench.path().join("images")).unwrap();
    std::fs::copy(
        assets_dir().join("photos/coffee.jpg"),
        bench.path().join("images/coffee.jpg"),
    )
    .unwrap();
    std::fs::create_dir_all(bench.path().join("data/coffee")).unwrap();
    std::fs::write(
        bench.path().join("data/coffee/labels.json"),
        r#"{"1": "black coffee", "2": "red saucer"}"#,
    )
    .unwrap();
    let server = start_server(Vec::new(), bench.path().into());
    let mut browser = Browser::start(1280, 800);
    let browser = &mut browser;

    // Segment: a negative click alone, and a map asked for with none.
    browser.open(
        &server.page("/?root=photos&path=coffee.jpg"),
        "document.getElementById('canvas').dataset.described === '1'",
    );
    assert_status_in_sight(browser, "segment");
    browser.right_click_canvas("#canvas", 150, 315);
    assert_error_in_sight(browser, "A negative click needs a positive one", "segment");
    browser.click("#save-map");
    assert_error_in_sight(browser, "No map yet", "segment");

    // Browse with no dataset.
    browser.open(
        &server.page("/browse"),
        "document.getElementById('status').textContent !== ''",
    );
    assert_error_in_sight(browser, "No dataset", "browse");

    // Evaluate with nothing annotated.
    browser.open(
        &server.page("/evaluate"),
        "document.querySelectorAll('#baselines input').length > 0",
    );
    browser.click("#run");
    assert_error_in_sight(browser, "no annotated image to evaluate", "evaluate");

    // Annotate: the groups named by labels.json; seven groups, Save and
    // "(saved)" in sight.
    browser.open(
        &server.page("/annotate"),
        "document.getElementById('canvas').dataset.image === 'coffee'",
    );
    browser.click("#relate-round");
    assert_error_in_sight(browser, "Tick two groups or more first.", "annotate");
    for g in 0..7 {
        if g > 0 {
            browser.click("#new-group");
        }
        browser.click_canvas("#canvas", 60 + 60 * g, 200, 0);
    }
    let named =
        browser.eval("[...document.querySelectorAll('#groups .name')].map((n) => n.placeholder)");
    assert_eq!(
        named,
        serde_json::json!([
            "black coffee",
            "red saucer",
            "name",
            "name",
            "name",
            "name",
            "name"
        ])
    );
    assert_in_sight(browser, "#save", "annotate");
    browser.click("#save");
    browser.wait_for("document.getElementById('canvas').dataset.saved === '1'");
    let said = browser.eval("document.getElementById('status').textContent");
    assert!(
        said.as_str()
            .unwrap()
            .starts_with("coffee: 7 groups, 7 points (saved)"),
        "{said}"
    );
    assert_status_in_sight(browser, "annotate");
    assert_in_sight(browser, "#save", "annotate");
    assert_fits_the_window(browser, "annotate");

    // Video with none to list, then a file that is not one.
    browser.open(
        &server.page("/video"),
        "document.getElementById('status').textContent !== ''",
    );
    assert_status_in_sight(browser, "video");
    let broken = bench.path().join("broken.mp4");
    std::fs::write(&broken, b"not a video at all").unwrap();
    browser.pick_files("#file", &[&broken]);
    assert_error_in_sight(browser, "broken.mp4: not a readable video", "video");
}
