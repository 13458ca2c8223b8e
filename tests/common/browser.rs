//! A headless Chromium driven over the Chrome DevTools Protocol (a WebSocket on loopback), for
//! the tests of the pages the service serves: load a URL, evaluate JavaScript in it, wait until
//! an expression holds. Chromium comes from the distribution (`scripts/test.sh` installs the
//! `chromium` package when it is missing); `SIGNORINI_CHROMIUM` names another binary. Without a
//! browser the test fails and says so: it is never skipped silently.

use super::{ChildGuard, PATIENCE};
use serde_json::{Value, json};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use tungstenite::{Message, WebSocket};

/// One headless Chromium with one page, killed on drop.
pub struct Browser {
    ws: WebSocket<TcpStream>,
    next_id: u64,
    _child: ChildGuard,
    _profile: tempfile::TempDir,
}

/// The Chromium binary: `SIGNORINI_CHROMIUM`, else the first of the usual names on `PATH`.
fn chromium() -> String {
    if let Ok(bin) = std::env::var("SIGNORINI_CHROMIUM") {
        return bin;
    }
    for name in ["chromium", "chromium-browser", "google-chrome"] {
        let found = Command::new("sh")
            .args(["-c", &format!("command -v {name}")])
            .output()
            .is_ok_and(|o| o.status.success());
        if found {
            return name.to_string();
        }
    }
    panic!(
        "no Chromium found (tried chromium, chromium-browser, google-chrome): the browser tests \
         need one; scripts/test.sh installs the distribution's `chromium` package, or set \
         SIGNORINI_CHROMIUM to a Chrome/Chromium binary"
    );
}

/// A blocking HTTP/1.1 GET on loopback (the DevTools HTTP endpoint), returning the body (read
/// to its `Content-Length`: the endpoint keeps the connection open).
fn http_get(port: u16, path: &str) -> String {
    let s = TcpStream::connect(("127.0.0.1", port)).expect("connecting to DevTools");
    let mut w = s.try_clone().expect("a second handle");
    write!(w, "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n")
        .expect("writing the request");
    let mut r = BufReader::new(s);
    let mut length = 0;
    loop {
        let mut line = String::new();
        r.read_line(&mut line).expect("reading a header");
        let line = line.trim_end();
        if line.is_empty() {
            break;
        }
        if let Some((k, v)) = line.split_once(':')
            && k.eq_ignore_ascii_case("content-length")
        {
            length = v.trim().parse().expect("a Content-Length");
        }
    }
    let mut body = vec![0; length];
    r.read_exact(&mut body).expect("reading the body");
    String::from_utf8(body).expect("a UTF-8 body")
}

impl Browser {
    /// Starts Chromium headless on an empty page and attaches to that page.
    pub fn launch() -> Browser {
        let profile = tempfile::tempdir().expect("a browser profile directory");
        let mut child = Command::new(chromium())
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                // WebGL on the CPU (SwiftShader): Chromium 137 and later no longer fall back to
                // it by themselves, and the rigid bodies' live page draws its 3D view in WebGL.
                "--enable-unsafe-swiftshader",
                "--disable-dev-shm-usage",
                "--no-first-run",
                "--remote-debugging-address=127.0.0.1",
                "--remote-debugging-port=0",
            ])
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .arg("about:blank")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("starting Chromium");
        // "DevTools listening on ws://127.0.0.1:PORT/devtools/browser/…" on stderr.
        let stderr = child.stderr.take().expect("piped stderr");
        let child = ChildGuard(child);
        let mut lines = BufReader::new(stderr).lines();
        let port: u16 = loop {
            let line = lines
                .next()
                .expect("Chromium exited before its DevTools endpoint was up")
                .expect("reading Chromium's stderr");
            if let Some(rest) = line.split("DevTools listening on ws://127.0.0.1:").nth(1) {
                break rest
                    .split('/')
                    .next()
                    .and_then(|p| p.parse().ok())
                    .expect("a DevTools port");
            }
        };
        // Keep draining stderr so Chromium never blocks on a full pipe.
        std::thread::spawn(move || lines.for_each(drop));
        // The about:blank page target can appear a moment after the endpoint.
        let start = Instant::now();
        let url = loop {
            let targets: Value =
                serde_json::from_str(&http_get(port, "/json/list")).expect("DevTools target list");
            let page = targets
                .as_array()
                .and_then(|ts| ts.iter().find(|t| t["type"] == "page"))
                .and_then(|t| t["webSocketDebuggerUrl"].as_str())
                .map(str::to_string);
            match page {
                Some(url) => break url,
                None if start.elapsed() < PATIENCE => std::thread::sleep(Duration::from_millis(50)),
                None => panic!("Chromium opened no page: {targets}"),
            }
        };
        let stream = TcpStream::connect(("127.0.0.1", port)).expect("connecting to the page");
        let (ws, _) = tungstenite::client(url.as_str(), stream).expect("DevTools WebSocket");
        Browser {
            ws,
            next_id: 1,
            _child: child,
            _profile: profile,
        }
    }

    /// Calls a DevTools method and returns its `result` (events in between are dropped).
    fn call(&mut self, method: &str, params: Value) -> Value {
        let id = self.next_id;
        self.next_id += 1;
        let msg = json!({ "id": id, "method": method, "params": params });
        self.ws
            .send(Message::text(msg.to_string()))
            .expect("sending a DevTools command");
        loop {
            let Message::Text(text) = self.ws.read().expect("reading from DevTools") else {
                continue;
            };
            let reply: Value = serde_json::from_str(&text).expect("DevTools JSON");
            if reply["id"] == id {
                assert!(reply["error"].is_null(), "{method}: {}", reply["error"]);
                return reply["result"].clone();
            }
        }
    }

    /// Loads `url` in the page.
    pub fn open(&mut self, url: &str) {
        let r = self.call("Page.navigate", json!({ "url": url }));
        assert!(r["errorText"].is_null(), "navigating to {url}: {r}");
    }

    /// The value of a JavaScript expression in the page (promises awaited).
    pub fn eval(&mut self, expression: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({ "expression": expression, "returnByValue": true, "awaitPromise": true }),
        );
        assert!(
            r["exceptionDetails"].is_null(),
            "{expression}: {}",
            r["exceptionDetails"]
        );
        r["result"]["value"].clone()
    }

    /// Waits until `expression` is truthy and returns its value; panics after [`PATIENCE`] with
    /// `what` and the page's text.
    pub fn wait_for(&mut self, what: &str, expression: &str) -> Value {
        let start = Instant::now();
        loop {
            let v = self.eval(&format!(
                "(() => {{ try {{ return {expression}; }} catch (e) {{ return null; }} }})()"
            ));
            let truthy = match &v {
                Value::Null => false,
                Value::Bool(b) => *b,
                Value::Number(n) => n.as_f64() != Some(0.0),
                Value::String(s) => !s.is_empty(),
                _ => true,
            };
            if truthy {
                return v;
            }
            if start.elapsed() > PATIENCE {
                let text = self.eval("document.body ? document.body.innerText : ''");
                panic!("waited {PATIENCE:?} for {what}; the page says: {text}");
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}
