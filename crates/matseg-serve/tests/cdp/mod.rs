//! A small Chrome DevTools Protocol driver for the browser tests: starts
//! the headless Chromium that `scripts/chromium-env.sh` installs, opens one
//! page, and evaluates scripts, clicks, uploads files and takes
//! screenshots in it over the protocol's WebSocket. JavaScript errors on
//! the page fail the call that sees them.

use serde_json::{json, Value};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

/// The DevTools protocol's field naming an attached page's channel.
const PAGE_CHANNEL: &str = "sessionId";

/// Key modifier bits of `Input.dispatchMouseEvent`.
pub const ALT: u32 = 1;
/// Control.
pub const CTRL: u32 = 2;
/// Shift.
pub const SHIFT: u32 = 8;

/// The browser: `MATSEG_CHROMIUM`, or the project's `.venv/chromium`.
fn browser_path() -> PathBuf {
    if let Some(path) = std::env::var_os("MATSEG_CHROMIUM") {
        return path.into();
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv/chromium/chromium");
    assert!(
        path.is_file(),
        "{}: no headless Chromium; run scripts/chromium-env.sh (make test does)",
        path.display()
    );
    path
}

/// A headless Chromium with one page open.
pub struct Browser {
    process: Child,
    socket: WebSocket<MaybeTlsStream<TcpStream>>,
    /// The protocol's id of the channel to the page, which every page
    /// command carries.
    page: String,
    next_id: u64,
    /// The messages of the dialogs (confirm, alert) the page opened.
    pub dialogs: Vec<String>,
    /// Whether dialogs are answered OK (else Cancel).
    pub accept_dialogs: bool,
    _profile: tempfile::TempDir,
}

impl Browser {
    /// Starts the browser with a window of `width x height` CSS pixels.
    pub fn start(width: u32, height: u32) -> Self {
        let profile = tempfile::tempdir().unwrap();
        let process = Command::new(browser_path())
            .args([
                "--no-sandbox",
                "--disable-gpu",
                "--remote-debugging-port=0",
                "--hide-scrollbars",
            ])
            .arg(format!("--window-size={width},{height}"))
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .arg("about:blank")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("the headless Chromium starts");
        // The browser writes its port and WebSocket path once it listens.
        let port_file = profile.path().join("DevToolsActivePort");
        let started = Instant::now();
        let text = loop {
            if let Ok(text) = std::fs::read_to_string(&port_file) {
                if text.lines().count() >= 2 {
                    break text;
                }
            }
            assert!(
                started.elapsed() < Duration::from_secs(30),
                "Chromium did not start"
            );
            std::thread::sleep(Duration::from_millis(50));
        };
        let mut lines = text.lines();
        let url = format!(
            "ws://127.0.0.1:{}{}",
            lines.next().unwrap(),
            lines.next().unwrap()
        );
        let (socket, _) = tungstenite::connect(url).expect("connects to the browser");
        let mut browser = Browser {
            process,
            socket,
            page: String::new(),
            next_id: 0,
            dialogs: Vec::new(),
            accept_dialogs: true,
            _profile: profile,
        };
        let target = browser.call_browser("Target.createTarget", json!({ "url": "about:blank" }));
        let attached = browser.call_browser(
            "Target.attachToTarget",
            json!({ "targetId": target["targetId"], "flatten": true }),
        );
        browser.page = attached[PAGE_CHANNEL].as_str().unwrap().to_string();
        browser.call("Runtime.enable", json!({}));
        browser.call("Page.enable", json!({}));
        browser.call(
            "Emulation.setDeviceMetricsOverride",
            json!({ "width": width, "height": height, "deviceScaleFactor": 1, "mobile": false }),
        );
        browser
    }

    fn send(&mut self, method: &str, params: Value, to_page: bool) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let mut message = json!({ "id": id, "method": method, "params": params });
        if to_page {
            message[PAGE_CHANNEL] = json!(self.page);
        }
        self.socket
            .send(Message::text(message.to_string()))
            .unwrap();
        loop {
            let text = match self.socket.read().expect("the browser answers") {
                Message::Text(text) => text,
                _ => continue,
            };
            let answer: Value = serde_json::from_str(text.as_str()).unwrap();
            if answer["method"] == "Runtime.exceptionThrown" {
                panic!(
                    "JavaScript error on the page: {}",
                    answer["params"]["exceptionDetails"]
                );
            }
            if answer["method"] == "Page.javascriptDialogOpening" {
                // Answered at once: the page waits for it, and so would
                // the command under way.
                self.dialogs.push(
                    answer["params"]["message"]
                        .as_str()
                        .unwrap_or_default()
                        .into(),
                );
                self.next_id += 1;
                let handle = json!({
                    "id": self.next_id,
                    "method": "Page.handleJavaScriptDialog",
                    "params": { "accept": self.accept_dialogs },
                    PAGE_CHANNEL: self.page,
                });
                self.socket.send(Message::text(handle.to_string())).unwrap();
                continue;
            }
            if answer["id"] == id {
                assert!(answer["error"].is_null(), "{method}: {}", answer["error"]);
                return answer["result"].clone();
            }
        }
    }

    fn call_browser(&mut self, method: &str, params: Value) -> Value {
        self.send(method, params, false)
    }

    /// Calls a protocol method on the page.
    pub fn call(&mut self, method: &str, params: Value) -> Value {
        self.send(method, params, true)
    }

    /// Opens `url` and waits until its scripts have run `ready`.
    pub fn open(&mut self, url: &str, ready: &str) {
        self.call("Page.navigate", json!({ "url": url }));
        self.wait_for(&format!("document.readyState === 'complete' && ({ready})"));
    }

    /// The value of the JavaScript expression `script` (awaited when a
    /// promise).
    pub fn eval(&mut self, script: &str) -> Value {
        let result = self.call(
            "Runtime.evaluate",
            json!({ "expression": script, "returnByValue": true, "awaitPromise": true }),
        );
        assert!(
            result["exceptionDetails"].is_null(),
            "{script}: {}",
            result["exceptionDetails"]
        );
        result["result"]["value"].clone()
    }

    /// Waits (up to a minute) until `script` is true; a timeout reports
    /// what the page's status line says.
    pub fn wait_for(&mut self, script: &str) {
        let started = Instant::now();
        while self.eval(&format!("Boolean({script})")) != json!(true) {
            if started.elapsed() > Duration::from_secs(60) {
                let status = self.eval("document.getElementById('status')?.textContent");
                panic!("timed out waiting for {script}; the page says {status}");
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Clicks at (x, y) in CSS pixels with `modifiers` held.
    pub fn click_at(&mut self, x: f64, y: f64, modifiers: u32) {
        self.press_button(x, y, "left", modifiers);
    }

    /// Presses and releases the mouse `button` (`left`, `right`) at (x, y).
    pub fn press_button(&mut self, x: f64, y: f64, button: &str, modifiers: u32) {
        for kind in ["mousePressed", "mouseReleased"] {
            self.call(
                "Input.dispatchMouseEvent",
                json!({ "type": kind, "x": x, "y": y, "button": button, "clickCount": 1, "modifiers": modifiers }),
            );
        }
    }

    /// Presses and releases the key `key` (a DOM key name: `z`, `Escape`)
    /// with `modifiers` held.
    pub fn press_key(&mut self, key: &str, modifiers: u32) {
        let code = match key {
            "Escape" => 27,
            _ => key.to_ascii_uppercase().bytes().next().map_or(0, u32::from),
        };
        let key = if modifiers & SHIFT != 0 && key.len() == 1 {
            key.to_ascii_uppercase()
        } else {
            key.to_string()
        };
        for kind in ["rawKeyDown", "keyUp"] {
            self.call(
                "Input.dispatchKeyEvent",
                json!({ "type": kind, "key": key, "windowsVirtualKeyCode": code, "modifiers": modifiers }),
            );
        }
    }

    /// Types `text` into the focused field, as a keyboard would.
    pub fn type_text(&mut self, text: &str) {
        self.call("Input.insertText", json!({ "text": text }));
    }

    /// Clicks the middle of the element `selector` finds.
    pub fn click(&mut self, selector: &str) {
        let centre = self.eval(&format!(
            "(() => {{ const e = document.querySelector({selector:?}); e.scrollIntoView({{ block: 'center' }});
               const b = e.getBoundingClientRect(); return [b.left + b.width / 2, b.top + b.height / 2]; }})()"
        ));
        self.click_at(centre[0].as_f64().unwrap(), centre[1].as_f64().unwrap(), 0);
    }

    /// Clicks the image pixel (x, y) of the canvas `selector` finds, drawn
    /// at whatever size the page gives it.
    pub fn click_canvas(&mut self, selector: &str, x: u32, y: u32, modifiers: u32) {
        self.press_canvas(selector, x, y, "left", modifiers);
    }

    /// Right-clicks the image pixel (x, y) of the canvas `selector` finds.
    pub fn right_click_canvas(&mut self, selector: &str, x: u32, y: u32) {
        self.press_canvas(selector, x, y, "right", 0);
    }

    /// Presses `button` on the image pixel (x, y) of the canvas `selector`
    /// finds, drawn at whatever size the page gives it.
    fn press_canvas(&mut self, selector: &str, x: u32, y: u32, button: &str, modifiers: u32) {
        let at = self.eval(&format!(
            "(() => {{ const c = document.querySelector({selector:?}); c.scrollIntoView({{ block: 'center' }});
               const b = c.getBoundingClientRect();
               return [b.left + ({x} + 0.5) * b.width / c.width, b.top + ({y} + 0.5) * b.height / c.height]; }})()"
        ));
        let (x, y) = (at[0].as_f64().unwrap(), at[1].as_f64().unwrap());
        self.press_button(x, y, button, modifiers);
    }

    /// The RGB of the pixel (x, y) of the canvas `selector` finds.
    pub fn canvas_pixel(&mut self, selector: &str, x: u32, y: u32) -> [i32; 3] {
        let rgba = self.eval(&format!(
            "Array.from(document.querySelector({selector:?}).getContext('2d').getImageData({x}, {y}, 1, 1).data)"
        ));
        [0, 1, 2].map(|c| rgba[c].as_i64().unwrap() as i32)
    }

    /// Sets the files of the file input `selector` finds (as a user picking
    /// them would).
    pub fn pick_files(&mut self, selector: &str, files: &[&Path]) {
        let document = self.call("DOM.getDocument", json!({}));
        let node = self.call(
            "DOM.querySelector",
            json!({ "nodeId": document["root"]["nodeId"], "selector": selector }),
        );
        // The browser reads files by their canonical path only.
        let files: Vec<String> = files
            .iter()
            .map(|f| f.canonicalize().unwrap().display().to_string())
            .collect();
        self.call(
            "DOM.setFileInputFiles",
            json!({ "nodeId": node["nodeId"], "files": files }),
        );
    }

    /// Lets the page's downloads go into `dir`.
    pub fn download_into(&mut self, dir: &Path) {
        self.call_browser(
            "Browser.setDownloadBehavior",
            json!({ "behavior": "allow", "downloadPath": dir.canonicalize().unwrap() }),
        );
    }

    /// A JPEG screenshot of the page as shown.
    pub fn screenshot(&mut self) -> Vec<u8> {
        let shot = self.call(
            "Page.captureScreenshot",
            json!({ "format": "jpeg", "quality": 85 }),
        );
        base64_decode(shot["data"].as_str().unwrap())
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.process.kill();
        let _ = self.process.wait();
    }
}

/// Standard base64 (with padding) to bytes.
fn base64_decode(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let bytes: Vec<u8> = text.bytes().filter(|&c| c != b'=').map(value).collect();
    bytes
        .chunks(4)
        .flat_map(|chunk| {
            let n = chunk.iter().fold(0u32, |n, &v| (n << 6) | v as u32) << (6 * (4 - chunk.len()));
            let out = [(n >> 16) as u8, (n >> 8) as u8, n as u8];
            out.into_iter().take(chunk.len() * 3 / 4)
        })
        .collect()
}
