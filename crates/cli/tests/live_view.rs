//! `truepos run --http`: the live view of a replay served over HTTP, checked with a plain TCP
//! client (std only): the page, the JSON API, the history from the log, the Server-Sent
//! Events stream resuming with `Last-Event-ID`, `/metrics` through `promtool check metrics`
//! (Debian `prometheus`, installed by scripts/install_prometheus.sh; missing, the test fails),
//! and the token beyond loopback. Every wait is bounded and every service is stopped.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

mod support;
use support::{command as truepos, scratch};

const TOKEN: &str = "live-view-token-0123456789abcdef";

/// A `truepos run` with the live view, stopped (SIGTERM, then SIGKILL) when dropped.
struct Running {
    child: Child,
    addr: SocketAddr,
    stderr: mpsc::Receiver<String>,
}

impl Running {
    fn start(extra: &[&str], db: &Path, token: Option<&str>) -> Self {
        let mut c = truepos();
        c.args([
            "run",
            "--source",
            "replay:examples/vmc3/run.csv@100",
            "--period-ms",
            "100",
            "--log",
        ])
        .arg(db)
        .args(extra)
        .env_remove("TRUEPOS_HTTP_TOKEN")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
        if let Some(t) = token {
            c.env("TRUEPOS_HTTP_TOKEN", t);
        }
        let mut child = c.spawn().unwrap();
        let (tx, rx) = mpsc::channel();
        let err = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(err).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let deadline = Instant::now() + Duration::from_secs(60);
        let mut seen = Vec::new();
        let addr = loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match rx.recv_timeout(left) {
                Ok(line) => {
                    if let Some(a) = line.strip_prefix("live view on http://") {
                        break a.trim_end_matches('/').parse::<SocketAddr>().unwrap();
                    }
                    seen.push(line);
                }
                Err(_) => {
                    let _ = child.kill();
                    panic!("no `live view on` line within 60 s: {seen:?}");
                }
            }
        };
        // A server bound to every address is reached through loopback.
        let addr = SocketAddr::from(([127, 0, 0, 1], addr.port()));
        let run = Self {
            child,
            addr,
            stderr: rx,
        };
        // The address is said before the first cycle; /api/state answers 503 until then.
        let bearer = format!("Authorization: Bearer {TOKEN}");
        while get(addr, "/api/state", &[&bearer]).status == 503 {
            assert!(Instant::now() < deadline, "no cycle published within 60 s");
            std::thread::sleep(Duration::from_millis(20));
        }
        run
    }

    /// SIGTERM and wait (at most 20 s) for a clean exit; its success and stderr.
    fn stop(mut self) -> (bool, String) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let deadline = Instant::now() + Duration::from_secs(20);
        let status = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break Some(s);
            }
            if Instant::now() > deadline {
                break None;
            }
            std::thread::sleep(Duration::from_millis(50));
        };
        let _ = self.child.kill();
        let _ = self.child.wait();
        let text: Vec<String> = self.stderr.try_iter().collect();
        (status.is_some_and(|s| s.success()), text.join("\n"))
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One response: status, head (lower-cased names), body.
struct Reply {
    status: u16,
    head: String,
    body: String,
}

/// A GET with the given extra header lines, over a fresh connection, bounded to 10 s.
fn get(addr: SocketAddr, target: &str, headers: &[&str]) -> Reply {
    request(addr, "GET", target, headers)
}

fn request(addr: SocketAddr, method: &str, target: &str, headers: &[&str]) -> Reply {
    let mut s = TcpStream::connect_timeout(&addr, Duration::from_secs(5)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut req = format!("{method} {target} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for h in headers {
        req += h;
        req += "\r\n";
    }
    req += "\r\n";
    s.write_all(req.as_bytes()).unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let text = String::from_utf8_lossy(&raw).into_owned();
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    Reply {
        status,
        head: head.to_lowercase(),
        body: body.to_string(),
    }
}

fn json(r: &Reply) -> serde_json::Value {
    assert_eq!(r.status, 200, "{}", r.body);
    serde_json::from_str(&r.body).unwrap_or_else(|e| panic!("{e}: {}", r.body))
}

/// Reads the event stream for `for_`: the (id, event type, data) of each message.
fn stream(
    addr: SocketAddr,
    last_event_id: Option<u64>,
    for_: Duration,
) -> Vec<(u64, String, String)> {
    let mut s = TcpStream::connect_timeout(&addr, Duration::from_secs(5)).unwrap();
    s.set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let mut req = format!("GET /events HTTP/1.1\r\nHost: {addr}\r\nAccept: text/event-stream\r\n");
    if let Some(id) = last_event_id {
        req += &format!("Last-Event-ID: {id}\r\n");
    }
    req += "\r\n";
    s.write_all(req.as_bytes()).unwrap();
    let deadline = Instant::now() + for_;
    let mut raw = Vec::new();
    let mut buf = [0u8; 65536];
    while Instant::now() < deadline {
        match s.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => raw.extend_from_slice(&buf[..n]),
            Err(_) => continue,
        }
    }
    let text = String::from_utf8_lossy(&raw).into_owned();
    let (head, body) = text.split_once("\r\n\r\n").unwrap();
    assert!(
        head.to_lowercase()
            .contains("content-type: text/event-stream"),
        "{head}"
    );
    body.split("\n\n")
        .filter_map(|block| {
            let mut id = None;
            let (mut kind, mut data) = (String::new(), String::new());
            for line in block.lines() {
                if let Some(v) = line.strip_prefix("id: ") {
                    id = v.parse().ok();
                } else if let Some(v) = line.strip_prefix("event: ") {
                    kind = v.into();
                } else if let Some(v) = line.strip_prefix("data: ") {
                    data = v.into();
                }
            }
            // A message cut by the end of the read has no data yet.
            Some((id?, kind, data)).filter(|m| !m.2.is_empty() && data_complete(&m.2))
        })
        .collect()
}

fn data_complete(data: &str) -> bool {
    serde_json::from_str::<serde_json::Value>(data).is_ok()
}

fn promtool_check(text: &str) {
    let promtool = ["/usr/bin/promtool", "/usr/local/bin/promtool"]
        .into_iter()
        .find(|p| Path::new(p).exists())
        .unwrap_or_else(|| {
            panic!("promtool is missing: run `bash scripts/install_prometheus.sh` (scripts/test.sh does)")
        });
    let mut child = Command::new(promtool)
        .args(["check", "metrics"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(text.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success() && out.stdout.is_empty() && out.stderr.is_empty(),
        "promtool check metrics: {}{}\n{text}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn the_live_view_serves_the_page_state_history_stream_and_metrics() {
    let dir = scratch("live-view");
    let db = dir.join("log.sqlite");
    let run = Running::start(&["--http", "127.0.0.1:0"], &db, None);
    let a = run.addr;

    let page = get(a, "/", &[]);
    assert_eq!(page.status, 200);
    assert!(
        page.head.contains("content-type: text/html"),
        "{}",
        page.head
    );
    assert!(page.body.len() < 100_000, "page {} bytes", page.body.len());
    assert!(page.body.contains("<canvas") && page.body.contains("EventSource"));
    for external in ["src=\"http", "href=\"http", "@import", "cdn"] {
        assert!(
            !page.body.contains(external),
            "the page fetches `{external}`"
        );
    }

    let info = json(&get(a, "/api/info", &[]));
    assert_eq!(info["axes"].as_array().unwrap().len(), 3, "{info}");
    assert_eq!(info["axes"][0]["unit"], "µm");
    assert_eq!(info["temperatures"][0]["unit"], "°C");
    assert_eq!(info["log"], true);

    let first = json(&get(a, "/api/state", &[]));
    std::thread::sleep(Duration::from_millis(600));
    let second = json(&get(a, "/api/state", &[]));
    assert_eq!(second["state"], "active", "{second}");
    assert!(
        second["time_s"].as_f64().unwrap() > first["time_s"].as_f64().unwrap(),
        "the state advances: {} then {}",
        first["time_s"],
        second["time_s"]
    );
    assert_eq!(second["paths"][0]["model"], "vmc3-example");
    assert_eq!(second["paths"][0]["generation"], 1);
    assert_eq!(second["temperatures"][0]["validation"], "ok");
    assert_eq!(second["sources"][0]["age_s"], 0.0, "delivering: {second}");
    // The cycle's work over the last minute, from every cycle since the server started.
    let work = &second["cycle_work"];
    assert!(work["cycles"].as_u64().unwrap() >= 5, "{second}");
    let (p50, p99, max) = (
        work["p50_us"].as_f64().unwrap(),
        work["p99_us"].as_f64().unwrap(),
        work["max_us"].as_f64().unwrap(),
    );
    assert!(0.0 < p50 && p50 <= p99 && p99 <= max * 1.1, "{work}");

    // The log commits every 250 ms: a second of history is there.
    std::thread::sleep(Duration::from_millis(700));
    let h = json(&get(a, "/api/history?window_s=100000&buckets=10", &[]));
    let buckets = h["buckets"].as_array().unwrap();
    assert!(!buckets.is_empty() && buckets.len() <= 11, "{h}");
    let cols: Vec<&str> = h["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    let z = cols.iter().position(|c| *c == "Z_offset_um").unwrap();
    // The model's target is history too (the dashed trace), not only live.
    let zt = cols.iter().position(|c| *c == "Z_target_um").unwrap();
    for b in buckets {
        let (lo, hi) = (b["min"][z].as_f64().unwrap(), b["max"][z].as_f64().unwrap());
        assert!(lo <= hi, "{b}");
        let (lo, hi) = (
            b["min"][zt].as_f64().unwrap(),
            b["max"][zt].as_f64().unwrap(),
        );
        assert!(lo <= hi && hi.is_finite(), "{b}");
    }
    let zipped = get(
        a,
        "/api/history?window_s=100000&buckets=10",
        &["Accept-Encoding: gzip, deflate"],
    );
    assert_eq!(zipped.status, 200);
    assert!(
        zipped.head.contains("content-encoding: gzip"),
        "{}",
        zipped.head
    );
    let page_zipped = get(a, "/", &["Accept-Encoding: gzip"]);
    assert!(
        page_zipped.head.contains("content-encoding: gzip"),
        "{}",
        page_zipped.head
    );
    let events = json(&get(a, "/api/events", &[]));
    assert!(
        events["events"]
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e["kind"] == "model-selected"),
        "{events}"
    );

    // The stream: a state message at least every 250 ms, numbered; resumed after an id.
    let got = stream(a, None, Duration::from_millis(1500));
    let states: Vec<&(u64, String, String)> = got.iter().filter(|m| m.1 == "state").collect();
    assert!(
        states.len() >= 5,
        "{} state messages in 1.5 s",
        states.len()
    );
    assert!(got.windows(2).all(|w| w[1].0 > w[0].0), "ids rise");
    let times: Vec<f64> = states
        .iter()
        .map(|m| {
            serde_json::from_str::<serde_json::Value>(&m.2).unwrap()["time_s"]
                .as_f64()
                .unwrap()
        })
        .collect();
    assert!(
        times.windows(2).all(|w| w[1] >= w[0]) && times.last() > times.first(),
        "{times:?}"
    );
    let from = got[1].0;
    let resumed = stream(a, Some(from), Duration::from_millis(400));
    assert_eq!(
        resumed.first().map(|m| m.0),
        Some(from + 1),
        "resumes after Last-Event-ID"
    );

    let m = get(a, "/metrics", &[]);
    assert_eq!(m.status, 200);
    assert!(
        m.head.contains("content-type: text/plain; version=0.0.4"),
        "{}",
        m.head
    );
    for name in [
        "truepos_cycles_total ",
        "truepos_late_cycles_total ",
        "truepos_sensor_faults{kind=\"stale\"} 0",
        "truepos_axis_clamps_total{axis=\"X\"} 0",
        "truepos_axis_offset_metres{axis=\"Z\"} ",
        "truepos_model_generation{model=\"vmc3-example\"} 1",
        "truepos_source_up{source=\"replay examples/vmc3/run.csv\"} 1",
        "truepos_compensation_active 1",
        "truepos_sensor_age_seconds{sensor=\"x_slide_top\"} ",
        "truepos_source_age_seconds{source=\"replay examples/vmc3/run.csv\"} 0",
        "# TYPE truepos_cycle_work_window_seconds summary",
        "truepos_cycle_work_window_seconds{quantile=\"0.99\"} ",
        "truepos_cycle_work_window_seconds_count ",
    ] {
        assert!(m.body.contains(name), "no `{name}` in\n{}", m.body);
    }
    promtool_check(&m.body);

    assert_eq!(get(a, "/nothing", &[]).status, 404);
    assert_eq!(
        request(a, "POST", "/api/state", &["Content-Length: 0"]).status,
        405
    );

    let (ok, stderr) = run.stop();
    assert!(ok, "the run ends cleanly on SIGTERM: {stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn beyond_loopback_the_live_view_needs_the_token_on_every_request() {
    let dir = scratch("live-token");
    let db = dir.join("log.sqlite");
    // Refused before anything runs: no token, or a short one.
    for (token, says) in [
        (None, "TRUEPOS_HTTP_TOKEN"),
        (Some("short"), "fewer than 16"),
    ] {
        let mut c = truepos();
        c.args(["run", "--fast", "--http", "0.0.0.0:0"])
            .env_remove("TRUEPOS_HTTP_TOKEN");
        if let Some(t) = token {
            c.env("TRUEPOS_HTTP_TOKEN", t);
        }
        let out = c.output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{err}");
        assert!(err.contains(says), "{err}");
        assert!(!err.contains("live view on"), "{err}");
    }

    let run = Running::start(&["--http", "0.0.0.0:0"], &db, Some(TOKEN));
    let a = run.addr;
    let wrong = "Authorization: Bearer live-view-token-0123456789abcdeX";
    for target in ["/", "/api/state", "/metrics", "/events", "/api/history"] {
        assert_eq!(get(a, target, &[]).status, 401, "{target} without a token");
        assert_eq!(
            get(a, target, &[wrong]).status,
            401,
            "{target} with a wrong token"
        );
        let q = format!("{target}?token=nope-nope-nope-nope");
        assert_eq!(get(a, &q, &[]).status, 401, "{q}");
    }
    let right = format!("Authorization: Bearer {TOKEN}");
    assert_eq!(get(a, "/api/state", &[&right]).status, 200);
    assert_eq!(get(a, &format!("/metrics?token={TOKEN}"), &[]).status, 200);
    assert_eq!(get(a, &format!("/?token={TOKEN}"), &[]).status, 200);
    let (ok, stderr) = run.stop();
    assert!(ok, "{stderr}");

    // The token from a file, the same way.
    let file = dir.join("token");
    std::fs::write(&file, format!("{TOKEN}\n")).unwrap();
    let file = file.display().to_string();
    let run = Running::start(
        &["--http", "0.0.0.0:0", "--http-token-file", &file],
        &db,
        None,
    );
    assert_eq!(get(run.addr, "/api/info", &[]).status, 401);
    assert_eq!(get(run.addr, "/api/info", &[&right]).status, 200);
    let (ok, stderr) = run.stop();
    assert!(ok, "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Headless Chromium (/usr/bin/chromium, scripts/install_chromium.sh) on `url`: the page's
/// `?selftest=N` verdict from `--dump-dom`, or a screenshot into `png`. Bounded to 60 s.
fn chromium(url: &str, window: &str, png: Option<&Path>, profile: &Path) -> String {
    let bin = Path::new("/usr/bin/chromium");
    assert!(
        bin.exists(),
        "/usr/bin/chromium is missing: run `bash scripts/install_chromium.sh` (scripts/test.sh does)"
    );
    let mut c = Command::new(bin);
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--no-first-run",
        "--hide-scrollbars",
        "--virtual-time-budget=3000",
    ])
    .arg(format!("--window-size={window}"))
    .arg(format!("--user-data-dir={}", profile.display()))
    .stdout(Stdio::piped())
    .stderr(Stdio::null());
    match png {
        Some(p) => c.arg(format!("--screenshot={}", p.display())),
        None => c.arg("--dump-dom"),
    };
    let mut child = c.arg(url).spawn().unwrap();
    let mut out = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("chromium did not finish within 60 s on {url}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    reader.join().unwrap()
}

/// The page's own verdict after `n` streamed state messages.
fn selftest(addr: SocketAddr, n: u32, profile: &Path) -> serde_json::Value {
    let dom = chromium(
        &format!("http://{addr}/?selftest={n}"),
        "1280,1000",
        None,
        profile,
    );
    // The last: the page's script mentions the element too.
    let start = dom
        .rfind("<pre id=\"selftest\">")
        .unwrap_or_else(|| panic!("no verdict from the page: {dom}"));
    let rest = &dom[start + "<pre id=\"selftest\">".len()..];
    let text = rest[..rest.find("</pre>").unwrap()]
        .replace("&quot;", "\"")
        .replace("&amp;", "&")
        .replace("&lt;", "<")
        .replace("&gt;", ">");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"))
}

/// The example run with temperature `x_slide_top`, which the model reads, out of its valid range
/// from 180 s of service time on.
fn faulty_run(dir: &Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(support::repo("examples/vmc3/run.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let col = header.split(',').position(|c| c == "x_slide_top").unwrap();
    let mut out = vec![header.to_string()];
    for line in lines {
        let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
        if cells[0].parse::<f64>().unwrap() >= 180.0 {
            cells[col] = "900".into();
        }
        out.push(cells.join(","));
    }
    let path = dir.join("faulty.csv");
    std::fs::write(&path, out.join("\n") + "\n").unwrap();
    path
}

#[test]
fn a_real_browser_draws_the_traces_and_cannot_miss_a_fault() {
    let dir = scratch("live-browser");
    let shots = Path::new(env!("CARGO_TARGET_TMPDIR")).parent().unwrap();
    let profile = dir.join("chromium-profile");

    let run = Running::start(&["--http", "127.0.0.1:0"], &dir.join("a.sqlite"), None);
    let v = selftest(run.addr, 5, &profile);
    assert_eq!(v["errors"], serde_json::json!([]), "console errors: {v}");
    assert_eq!(v["streamed"], 5, "{v}");
    assert_eq!(v["traces"], 3, "a trace per axis: {v}");
    assert!(
        v["last_t"].as_f64().unwrap() > v["first_t"].as_f64().unwrap(),
        "the traces advance: {v}"
    );
    assert_eq!(v["banner"], "", "no banner while active: {v}");
    for (name, window) in [("desktop", "1280,1100"), ("phone", "390,1700")] {
        let png = shots.join(format!("live_view_{name}.png"));
        let _ = std::fs::remove_file(&png);
        chromium(
            &format!("http://{}/?selftest=8", run.addr),
            window,
            Some(&png),
            &profile,
        );
        assert!(
            std::fs::metadata(&png).is_ok_and(|m| m.len() > 10_000),
            "{}",
            png.display()
        );
    }
    let (ok, stderr) = run.stop();
    assert!(ok, "{stderr}");

    let faulty = faulty_run(&dir);
    let source = format!("replay:{}@100", faulty.display());
    let run = Running::start(
        &["--source", &source, "--http", "127.0.0.1:0"],
        &dir.join("b.sqlite"),
        None,
    );
    let deadline = Instant::now() + Duration::from_secs(20);
    // 503 until the first cycle is published, then active until the fault.
    loop {
        let r = get(run.addr, "/api/state", &[]);
        if r.status == 200 && json(&r)["state"] != "active" {
            break;
        }
        assert!(Instant::now() < deadline, "the fault never took effect");
        std::thread::sleep(Duration::from_millis(100));
    }
    // The log commits every 250 ms; the page reads the events at load.
    std::thread::sleep(Duration::from_millis(600));
    let v = selftest(run.addr, 3, &profile);
    assert_eq!(v["errors"], serde_json::json!([]), "console errors: {v}");
    let banner = v["banner"].as_str().unwrap();
    assert!(banner.contains("COMPENSATION NOT ACTIVE: holding"), "{v}");
    // The 900 °C reading is outside x_slide_top's valid range: marked, not scaled to.
    let top = v["temps_scale"][1].as_f64().unwrap();
    assert!(
        top < 100.0,
        "the temperature plot scaled to a faulty reading: {v}"
    );
    assert!(
        v["events"].as_u64().unwrap() >= 2,
        "sensor-fault listed: {v}"
    );
    // A page opened later (a reload) starts from the log's history of the run, from its start.
    assert!(v["history_buckets"].as_u64().unwrap() >= 10, "{v}");
    let again = selftest(run.addr, 2, &profile);
    assert!(
        again["history_buckets"].as_u64() >= v["history_buckets"].as_u64()
            && again["history_from"] == 0.0,
        "{again}"
    );
    let png = shots.join("live_view_fault.png");
    chromium(
        &format!("http://{}/?selftest=3", run.addr),
        "1280,1100",
        Some(&png),
        &profile,
    );
    let (ok, stderr) = run.stop();
    assert!(ok, "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A model file changed under `--reload-on-change` shows as the next generation in the state and
/// the metrics, and its reload as an event.
#[test]
fn a_reloaded_model_shows_its_new_generation() {
    let dir = scratch("live-reload");
    let model = dir.join("model.toml");
    let text = std::fs::read_to_string(support::repo("examples/vmc3/model.toml")).unwrap();
    std::fs::write(&model, &text).unwrap();
    let models = model.display().to_string();
    let run = Running::start(
        &[
            "--models",
            &models,
            "--reload-on-change",
            "--http",
            "127.0.0.1:0",
        ],
        &dir.join("log.sqlite"),
        None,
    );
    let a = run.addr;
    assert_eq!(
        json(&get(a, "/api/state", &[]))["paths"][0]["generation"],
        1
    );
    std::fs::write(&model, format!("{text}\n# re-identified\n")).unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    while json(&get(a, "/api/state", &[]))["paths"][0]["generation"] != 2 {
        assert!(Instant::now() < deadline, "generation 2 never shown");
        std::thread::sleep(Duration::from_millis(100));
    }
    let m = get(a, "/metrics", &[]).body;
    assert!(
        m.contains("truepos_model_generation{model=\"vmc3-example\"} 2"),
        "{m}"
    );
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let events = json(&get(a, "/api/events", &[]));
        let kinds: Vec<&str> = events["events"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|e| e["kind"].as_str())
            .collect();
        if kinds.contains(&"model-reloaded") {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "no model-reloaded event: {kinds:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let (ok, stderr) = run.stop();
    assert!(ok, "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// An axis held at its envelope (the example machine with Z's `max_offset_um` at 15 µm, below
/// the model's 28 µm) raises the banner although the state is `active`, and counts the clamp.
#[test]
fn a_clamped_axis_raises_the_banner_in_the_browser() {
    let dir = scratch("live-clamp");
    let text = std::fs::read_to_string(support::repo("examples/vmc3/machine.toml")).unwrap();
    let z = "name = \"Z\"\nkind = \"linear\"\ntravel = [0.0, 500.0]\ncarriage = \"cantilever\"\n";
    assert!(text.contains(z), "the example machine's Z changed");
    let machine = dir.join("machine.toml");
    std::fs::write(
        &machine,
        text.replace(z, &format!("{z}max_offset_um = 15.0\n")),
    )
    .unwrap();
    let machine = machine.display().to_string();
    let run = Running::start(
        &["--machine", &machine, "--http", "127.0.0.1:0"],
        &dir.join("log.sqlite"),
        None,
    );
    let a = run.addr;
    let deadline = Instant::now() + Duration::from_secs(30);
    let state = loop {
        let v = json(&get(a, "/api/state", &[]));
        if v["clamped"] == true {
            break v;
        }
        assert!(Instant::now() < deadline, "Z never clamped: {v}");
        std::thread::sleep(Duration::from_millis(100));
    };
    assert_eq!(state["state"], "active", "{state}");
    assert_eq!(state["axes"][2]["offset"], -15.0, "{state}");
    let m = get(a, "/metrics", &[]).body;
    assert!(m.contains("truepos_axis_clamps_total{axis=\"Z\"} 1"), "{m}");
    assert!(m.contains("truepos_clamped 1"), "{m}");
    promtool_check(&m);
    let profile = dir.join("chromium-profile");
    let v = selftest(a, 3, &profile);
    assert_eq!(v["errors"], serde_json::json!([]), "console errors: {v}");
    let banner = v["banner"].as_str().unwrap();
    assert!(
        banner.contains("OUTPUT CLAMPED by the safety envelope on Z"),
        "{v}"
    );
    let shots = Path::new(env!("CARGO_TARGET_TMPDIR")).parent().unwrap();
    chromium(
        &format!("http://{a}/?selftest=3"),
        "1280,1100",
        Some(&shots.join("live_view_clamp.png")),
        &profile,
    );
    let (ok, stderr) = run.stop();
    assert!(ok, "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The example model with validation figures in its file (a `[validation]` table and a fit's
/// inner cross-validation error in `[provenance]`), and the example run with four probe events on Z.
fn model_and_probes(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let text = std::fs::read_to_string(support::repo("examples/vmc3/model.toml")).unwrap();
    let at = "[provenance]\n";
    assert!(text.contains(at), "the example model has no [provenance]");
    let model = dir.join("validated.toml");
    std::fs::write(
        &model,
        text.replace(at, &format!("{at}Z_inner_cv_rmse_um = 1.75\n"))
            + "\n[validation]\nwindow_measurements = 30\nwindow_old_rmse_um = 4.25\nwindow_new_rmse_um = 1.5\n",
    )
    .unwrap();
    let run = std::fs::read_to_string(support::repo("examples/vmc3/run.csv")).unwrap();
    let mut lines = run.lines();
    let mut out = vec![format!("{},probe_z_mm,probe_dz_um", lines.next().unwrap())];
    for line in lines {
        let t: f64 = line.split(',').next().unwrap().parse().unwrap();
        let probe = match t as i64 {
            60 => "250,2.5",
            120 => "250,4.5",
            180 => "250,7.5",
            240 => "250,9.0",
            _ => ",",
        };
        out.push(format!("{line},{probe}"));
    }
    let probes = dir.join("probes.csv");
    std::fs::write(&probes, out.join("\n") + "\n").unwrap();
    (model, probes)
}

/// The model-quality panel: the validation figures the model file carries and the residuals of
/// the run's probe events (measured − predicted, from the log), in `/api/quality` and on the
/// page, with the probe events listed among the events.
#[test]
fn the_model_quality_shows_the_files_validation_and_the_probe_residuals() {
    let dir = scratch("live-quality");
    let (model, probes) = model_and_probes(&dir);
    let models = model.display().to_string();
    let source = format!("probes:{}@100", probes.display());
    let run = Running::start(
        &[
            "--models",
            &models,
            "--source",
            &source,
            "--http",
            "127.0.0.1:0",
        ],
        &dir.join("log.sqlite"),
        None,
    );
    let a = run.addr;
    let deadline = Instant::now() + Duration::from_secs(30);
    let q = loop {
        let q = json(&get(a, "/api/quality", &[]));
        if q["probes"]["count"].as_u64() >= Some(4) {
            break q;
        }
        assert!(
            Instant::now() < deadline,
            "four probe events never logged: {q}"
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    let m = &q["models"][0];
    assert_eq!(m["name"], "vmc3-example", "{q}");
    assert_eq!(m["generation"], 1, "{q}");
    let figure = |key: &str| {
        m["figures"]
            .as_array()
            .unwrap()
            .iter()
            .find(|f| f["key"] == key)
            .unwrap_or_else(|| panic!("no {key}: {q}"))["value"]
            .as_f64()
            .unwrap()
    };
    assert_eq!(figure("window_new_rmse_um"), 1.5);
    assert_eq!(figure("window_measurements"), 30.0);
    assert_eq!(figure("Z_inner_cv_rmse_um"), 1.75);
    let events = q["probes"]["events"].as_array().unwrap();
    assert_eq!(events.len(), 4, "{q}");
    let mut sum = 0.0;
    for (e, measured) in events.iter().zip([2.5, 4.5, 7.5, 9.0]) {
        assert_eq!(e["accepted"], true, "{e}");
        let z = &e["axes"][0];
        assert_eq!(z["axis"], "Z", "{e}");
        assert_eq!(z["measured_um"], measured, "{e}");
        let (p, r) = (
            z["predicted_um"].as_f64().unwrap(),
            z["residual_um"].as_f64().unwrap(),
        );
        assert!(
            (r - (measured - p)).abs() < 1e-9,
            "residual = measured − predicted: {e}"
        );
        sum += r * r;
    }
    let rms = q["probes"]["residual_rms"]["Z"]["rms_um"].as_f64().unwrap();
    assert!((rms - (sum / 4.0).sqrt()).abs() < 1e-9, "{q}");

    let profile = dir.join("chromium-profile");
    let v = selftest(a, 3, &profile);
    assert_eq!(v["errors"], serde_json::json!([]), "console errors: {v}");
    assert_eq!(v["quality_models"], 1, "{v}");
    assert!(v["quality_figures"].as_u64() >= Some(3), "{v}");
    assert_eq!(v["probes"], 4, "{v}");
    let shots = Path::new(env!("CARGO_TARGET_TMPDIR")).parent().unwrap();
    chromium(
        &format!("http://{a}/?selftest=3"),
        "1280,1400",
        Some(&shots.join("live_view_quality.png")),
        &profile,
    );
    let (ok, stderr) = run.stop();
    assert!(ok, "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Reads what has arrived on `s` within `for_` (the stream's head and messages so far).
fn read_for(s: &mut TcpStream, for_: Duration) -> String {
    s.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
    let deadline = Instant::now() + for_;
    let mut raw = Vec::new();
    let mut buf = [0u8; 65536];
    while Instant::now() < deadline {
        match s.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => raw.extend_from_slice(&buf[..n]),
            Err(_) => continue,
        }
    }
    String::from_utf8_lossy(&raw).into_owned()
}

/// Sixteen pages' streams at once are all served at the stream's rate (the issue asks ten), a
/// seventeenth is refused with 503 while requests are still answered; connections beyond the
/// server's bound (24) are answered 503 at once, without a thread, and the server serves again
/// when they close.
#[test]
fn sixteen_pages_stream_at_once_and_more_are_refused_cleanly() {
    let dir = scratch("live-bound");
    let run = Running::start(&["--http", "127.0.0.1:0"], &dir.join("log.sqlite"), None);
    let a = run.addr;
    let open = |target: &str| {
        let mut s = TcpStream::connect_timeout(&a, Duration::from_secs(5)).unwrap();
        s.write_all(format!("GET {target} HTTP/1.1\r\nHost: {a}\r\n\r\n").as_bytes())
            .unwrap();
        s
    };
    let mut pages: Vec<TcpStream> = (0..16).map(|_| open("/events")).collect();
    std::thread::sleep(Duration::from_millis(300));
    let refused = read_for(&mut open("/events"), Duration::from_millis(500));
    assert!(refused.starts_with("HTTP/1.1 503"), "{refused}");
    assert_eq!(
        get(a, "/api/state", &[]).status,
        200,
        "requests answered beside 16 streams"
    );
    std::thread::sleep(Duration::from_millis(1200));
    for (i, p) in pages.iter_mut().enumerate() {
        let got = read_for(p, Duration::from_millis(100));
        assert!(got.starts_with("HTTP/1.1 200"), "page {i}: {got}");
        let states = got.matches("event: state\n").count();
        assert!(states >= 5, "page {i}: {states} state messages in 1.5 s");
    }
    // The server's bound: 16 streams and 8 idle connections fill it.
    let idle: Vec<TcpStream> = (0..8)
        .map(|_| TcpStream::connect_timeout(&a, Duration::from_secs(5)).unwrap())
        .collect();
    std::thread::sleep(Duration::from_millis(300));
    let busy = get(a, "/api/state", &[]);
    assert_eq!(busy.status, 503, "{}", busy.body);
    assert!(busy.head.contains("retry-after: 5"), "{}", busy.head);
    drop(idle);
    drop(pages);
    let deadline = Instant::now() + Duration::from_secs(10);
    while get(a, "/api/state", &[]).status != 200 {
        assert!(
            Instant::now() < deadline,
            "not served again after the connections closed"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let (ok, stderr) = run.stop();
    assert!(ok, "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}
