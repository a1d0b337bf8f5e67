//! `physid live` with its panel: a real Chromium over WebDriver drives the page on the virtual
//! cell; plain HTTP clients check reconnecting, a slow client, malformed controls and the
//! token rule. Everything listens on 127.0.0.1 on ports the system picks.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::physid;
use fantoccini::Locator;
use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// `physid live` with its panel, killed when dropped.
struct Live {
    child: Child,
    addr: SocketAddr,
    url: String,
}

impl Live {
    /// Start `physid live ARGS --port 0` and read the address it prints.
    fn start(args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_physid"))
            .arg("live")
            .args(args)
            .args(["--port", "0"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start physid live");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let url = line
            .trim()
            .strip_prefix("physid live: panel at ")
            .unwrap_or_else(|| panic!("no address printed: {line:?}"))
            .to_string();
        let hostport = url
            .strip_prefix("http://")
            .unwrap()
            .split('/')
            .next()
            .unwrap();
        Live {
            child,
            addr: hostport.parse().unwrap(),
            url,
        }
    }
}

impl Drop for Live {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One HTTP/1.0 request; the status and the body.
fn http(addr: SocketAddr, method: &str, path: &str, headers: &[&str], body: &str) -> (u16, String) {
    http_to(addr, &addr.to_string(), method, path, headers, body)
}

/// One HTTP/1.0 request to `addr` naming `host` in its `Host` header.
fn http_to(
    addr: SocketAddr,
    host: &str,
    method: &str,
    path: &str,
    headers: &[&str],
    body: &str,
) -> (u16, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let mut req = format!("{method} {path} HTTP/1.0\r\nHost: {host}\r\n");
    for h in headers {
        req += &format!("{h}\r\n");
    }
    req += &format!("Content-Length: {}\r\n\r\n{body}", body.len());
    s.write_all(req.as_bytes()).unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    let status = text[9..12].parse().unwrap();
    let body = text.split_once("\r\n\r\n").map_or("", |b| b.1).to_string();
    (status, body)
}

/// POST a JSON body to the panel's API.
fn post(addr: SocketAddr, path: &str, body: &str) -> (u16, Value) {
    let (code, text) = http(
        addr,
        "POST",
        path,
        &["Content-Type: application/json"],
        body,
    );
    (code, serde_json::from_str(&text).unwrap_or(Value::Null))
}

/// The event stream as a client reads it: (number, event).
struct Sse {
    reader: BufReader<TcpStream>,
}

impl Sse {
    fn connect(addr: SocketAddr, path: &str) -> Self {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        write!(s, "GET {path} HTTP/1.0\r\nHost: {addr}\r\n\r\n").unwrap();
        let mut reader = BufReader::new(s);
        let mut line = String::new();
        reader.read_line(&mut line).unwrap();
        assert!(line.contains(" 200 "), "{path}: {line}");
        // Past the headers.
        while line.trim() != "" {
            line.clear();
            reader.read_line(&mut line).unwrap();
        }
        Sse { reader }
    }

    /// The next event (its `id`, 0 when it has none), or `None` at the end of the stream or
    /// at `deadline` (keep-alive comments do not count as events).
    fn next(&mut self, deadline: Instant) -> Option<(u64, Value)> {
        let (mut id, mut line) = (0, String::new());
        loop {
            let left = deadline.checked_duration_since(Instant::now())?;
            let wait = left.max(Duration::from_millis(1));
            self.reader.get_ref().set_read_timeout(Some(wait)).ok()?;
            line.clear();
            if self.reader.read_line(&mut line).ok()? == 0 {
                return None;
            }
            if let Some(v) = line.strip_prefix("id: ") {
                id = v.trim().parse().unwrap();
            } else if let Some(d) = line.strip_prefix("data: ") {
                return Some((id, serde_json::from_str(d).unwrap()));
            }
        }
    }

    /// Events until `stop` says so (which it is given too), within `secs` of wall clock.
    fn until(&mut self, secs: u64, mut stop: impl FnMut(&Value) -> bool) -> Vec<(u64, Value)> {
        let deadline = Instant::now() + Duration::from_secs(secs);
        let mut out = Vec::new();
        while let Some(e) = self.next(deadline) {
            let done = stop(&e.1);
            out.push(e);
            if done {
                return out;
            }
        }
        panic!(
            "the awaited event did not come within {secs} s; the last: {:?}",
            out.last()
        );
    }
}

/// A client that leaves and comes back finds the run going: hello, what it missed (the alarm
/// it saw, with the same number, and the estimates before), then the live events — numbers
/// increasing, none twice — to the end.
#[test]
fn a_client_that_reconnects_catches_up() {
    let live = Live::start(&[
        "--scenario",
        "shaft-steady",
        "--duration",
        "6",
        "--fault",
        "shaft.k=1000@2",
        "--pace",
        "4",
    ]);
    let mut a = Sse::connect(live.addr, "/api/events");
    let first = a.until(30, |e| e["type"] == "alarm");
    assert_eq!(first[0].1["type"], "hello");
    let (alarm_seq, alarm) = first.last().unwrap().clone();
    assert_eq!(alarm["param"], "K");
    drop(a);
    std::thread::sleep(Duration::from_millis(500));
    let mut b = Sse::connect(live.addr, "/api/events");
    let again = b.until(30, |e| e["type"] == "end");
    assert_eq!(again[0].1["type"], "hello");
    assert!(
        again.iter().any(|(s, e)| *s == alarm_seq && *e == alarm),
        "the alarm is in the backlog with its number"
    );
    let ids: Vec<u64> = again[1..].iter().map(|(s, _)| *s).collect();
    assert!(
        ids.windows(2).all(|w| w[1] > w[0]),
        "numbers increase, none repeated"
    );
    let first_estimate = again.iter().find(|(_, e)| e["type"] == "estimate").unwrap();
    assert!(
        first_estimate.1["t_s"].as_f64().unwrap() < 0.2,
        "the backlog goes back to the start"
    );
    assert!(again
        .iter()
        .any(|(_, e)| e["type"] == "cycle" && e["curve"]["p_cyl"].is_array()));
}

/// A client that does not read is not waited for: the run reaches its end (a reading client
/// sees it) while the slow one sits; the slow one is then told how many events it lost, and
/// the panel counts them.
#[test]
fn a_slow_client_loses_events_and_the_run_does_not_wait() {
    let live = Live::start(&[
        "--scenario",
        "shaft-steady",
        "--duration",
        "200",
        "--pace",
        "max",
    ]);
    // Connect the slow client first, and never read until the end.
    let mut slow = Sse::connect(live.addr, "/api/events");
    let mut fast = Sse::connect(live.addr, "/api/events");
    let seen = fast.until(120, |e| e["type"] == "end");
    assert!(seen.last().unwrap().1["samples"].as_u64().unwrap() > 1_900_000);
    let mut lost = 0;
    let rest = slow.until(60, |e| {
        lost += e["dropped"]
            .as_u64()
            .filter(|_| e["type"] == "lagged")
            .unwrap_or(0);
        e["type"] == "end"
    });
    assert!(
        lost > 0,
        "the slow client lost events and was told ({} read)",
        rest.len()
    );
    let (code, status) = http(live.addr, "GET", "/api/status", &[], "");
    assert_eq!(code, 200);
    let status: Value = serde_json::from_str(&status).unwrap();
    assert!(status["lagged"].as_u64().unwrap() >= lost, "{status}");
}

/// Malformed control messages get an error naming the field (or what is wrong) and the run goes
/// on; pause holds the run, resume continues it.
#[test]
fn malformed_controls_are_refused_by_name_and_the_run_goes_on() {
    let live = Live::start(&[
        "--scenario",
        "shaft-steady",
        "--duration",
        "60",
        "--pace",
        "2",
    ]);
    let mut sse = Sse::connect(live.addr, "/api/events");
    sse.until(30, |e| {
        e["type"] == "estimate" && e["t_s"].as_f64().unwrap() > 0.3
    });
    for (body, want) in [
        (r#"{"cmd":"speed","rpm":"fast"}"#, "field 'rpm'"),
        (r#"{"cmd":"throttle","deg":400}"#, "field 'deg'"),
        (r#"{"cmd":"fault","spec":"shaft.q=1@1"}"#, "field 'spec'"),
        (r#"{"cmd":"warp"}"#, "field 'cmd' is 'warp'"),
        (r#"{"rpm":1}"#, "field 'cmd' is missing"),
        ("speed 1200", "not a JSON object"),
    ] {
        let (code, reply) = post(live.addr, "/api/control", body);
        assert_eq!(code, 400, "{body}: {reply}");
        assert_eq!(reply["ok"], false);
        assert!(
            reply["error"].as_str().unwrap().contains(want),
            "{body}: {reply}"
        );
    }
    // Not declared JSON (a cross-site form), or from another origin: refused.
    let (code, _) = http(
        live.addr,
        "POST",
        "/api/control",
        &["Content-Type: text/plain"],
        r#"{"cmd":"stop"}"#,
    );
    assert_eq!(code, 415);
    let (code, _) = http(
        live.addr,
        "POST",
        "/api/control",
        &[
            "Content-Type: application/json",
            "Origin: http://example.com",
        ],
        r#"{"cmd":"stop"}"#,
    );
    assert_eq!(code, 403);
    let (code, reply) = post(live.addr, "/api/ack", r#"{"seq": 1}"#);
    assert_eq!(
        (
            code,
            reply["error"].as_str().unwrap().contains("not an alarm")
        ),
        (400, true)
    );
    // The run went on: each refusal the run saw is an error event (the body that is not JSON
    // was refused at the door), and estimates follow.
    let errors = sse.until(30, |e| {
        e["type"] == "error" && e["message"].as_str().unwrap().contains("'cmd' is missing")
    });
    assert_eq!(
        errors.iter().filter(|(_, e)| e["type"] == "error").count(),
        5
    );
    let (code, reply) = post(live.addr, "/api/control", r#"{"cmd":"speed","rpm":1200}"#);
    assert_eq!((code, &reply["cmd"]), (200, &json!("speed")));
    // Pause: nothing newer than the pause comes; resume: the run continues.
    let (code, _) = post(live.addr, "/api/control", r#"{"cmd":"pause"}"#);
    assert_eq!(code, 200);
    let paused = sse.until(30, |e| e["type"] == "control" && e["cmd"] == "pause");
    let t_pause = paused.last().unwrap().1["t_s"].as_f64().unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    assert_eq!(
        post(live.addr, "/api/control", r#"{"cmd":"resume"}"#).0,
        200
    );
    // In the stream, whatever came while paused lies between the two control events.
    let held = sse.until(30, |e| e["type"] == "control" && e["cmd"] == "resume");
    for (_, e) in &held {
        let t = e["t_s"].as_f64().unwrap_or(0.0);
        assert!(t <= t_pause + 0.011, "{e} while paused at {t_pause} s");
    }
    sse.until(30, |e| {
        e["type"] == "estimate" && e["t_s"].as_f64().unwrap() > t_pause + 0.5
    });
    // A stop while paused ends the run (long before its 60 s).
    assert_eq!(post(live.addr, "/api/control", r#"{"cmd":"pause"}"#).0, 200);
    assert_eq!(post(live.addr, "/api/control", r#"{"cmd":"stop"}"#).0, 200);
    let end = sse.until(30, |e| e["type"] == "end");
    assert!(end.last().unwrap().1["t_s"].as_f64().unwrap() < 30.0);
}

/// The token rule: beyond loopback only with a token; with one, the API refuses requests
/// without it (the page itself is served to anyone who can reach it).
#[test]
fn the_token_rule() {
    let o = physid(&["live", "--bind", "0.0.0.0", "--duration", "1"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--token"), "{err}");
    let o = physid(&["live", "--token", "short", "--duration", "1"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("at least 8"));
    let token = "s3cret-panel-token";
    let live = Live::start(&["--token", token, "--duration", "30"]);
    assert!(
        live.url.ends_with(&format!("?token={token}")),
        "{}",
        live.url
    );
    for (path, headers, want) in [
        ("/api/status".to_string(), vec![], 401),
        ("/api/status?token=wrong-token-xx".into(), vec![], 401),
        (format!("/api/status?token={token}"), vec![], 200),
        (
            "/api/status".into(),
            vec![format!("Authorization: Bearer {token}")],
            200,
        ),
        ("/api/events".into(), vec![], 401),
        ("/".into(), vec![], 200),
        ("/assets/panel.js".into(), vec![], 200),
        ("/assets/nothing.js".into(), vec![], 404),
    ] {
        let h: Vec<&str> = headers.iter().map(String::as_str).collect();
        assert_eq!(
            http(live.addr, "GET", &path, &h, "").0,
            want,
            "{path} {headers:?}"
        );
    }
    let (code, body) = http(
        live.addr,
        "POST",
        "/api/control",
        &["Content-Type: application/json"],
        r#"{"cmd":"stop"}"#,
    );
    assert_eq!(code, 401, "{body}");
}

/// The Host rule (DNS rebinding): a page of another site whose name resolves to 127.0.0.1
/// sends its own name as `Host` and is refused on every route — though it comes from
/// 127.0.0.1, and though its `Origin` matches its `Host`; the panel's own names pass
/// (127.0.0.1, localhost, [::1] on loopback, a name given to --bind or --allow-host). The
/// token from PHYSID_TOKEN or --token-file, kept out of the process list; an error quotes at
/// most a few hundred bytes of what it was sent; a 1 MB control is refused unread.
/// Idle connections do not take the service's file descriptors: 400 clients that open a
/// connection and send half a header (a scanner, a script gone wrong, a stranger on the
/// network) hold at most `MAX_CONNECTIONS` (256) of the process's descriptors — the ones past
/// it are closed at once — and each is closed by the service when its header has not come in
/// `HEADER_TIMEOUT` (10 s); the panel then answers again. Before, every connection was held
/// for ever: 12 000 of them took 12 000 descriptors, and past the process's limit a log could
/// not be opened. The run and its events go on meanwhile.
#[test]
fn idle_connections_are_capped_and_timed_out() {
    let live = Live::start(&["--duration", "120", "--pace", "1"]);
    let fds = || {
        std::fs::read_dir(format!("/proc/{}/fd", live.child.id()))
            .map(|d| d.count())
            .unwrap_or(0)
    };
    let before = fds();
    let mut held = Vec::new();
    for _ in 0..400 {
        let mut s = TcpStream::connect(live.addr).unwrap();
        s.write_all(b"GET /api/status HTTP/1.1\r\nHo").unwrap();
        held.push(s);
    }
    // The service has taken them all (the ones past the cap closed): poll briefly.
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut most = 0;
    while Instant::now() < deadline {
        most = most.max(fds());
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        most <= before + 256 + 16,
        "the service held {most} descriptors ({before} before 400 idle connections)"
    );
    // Each idle connection is closed by the service: its read ends (EOF or reset).
    let deadline = Instant::now() + Duration::from_secs(40);
    for s in &mut held {
        s.set_read_timeout(Some(Duration::from_secs(1))).unwrap();
        let mut buf = [0u8; 64];
        loop {
            match s.read(&mut buf) {
                Ok(0) => break,
                Ok(_) => {}
                Err(e)
                    if e.kind() == std::io::ErrorKind::WouldBlock
                        || e.kind() == std::io::ErrorKind::TimedOut =>
                {
                    assert!(
                        Instant::now() < deadline,
                        "an idle connection held past 40 s"
                    );
                }
                Err(_) => break,
            }
        }
    }
    let (code, text) = http(live.addr, "GET", "/api/status", &[], "");
    assert_eq!(code, 200, "{text}");
    assert!(
        fds() <= before + 16,
        "{} descriptors after the idle ones closed",
        fds()
    );
}

#[test]
fn the_host_rule_refuses_dns_rebinding() {
    let live = Live::start(&["--duration", "60", "--allow-host", "cell-7.lab.example"]);
    let port = live.addr.port();
    let fault = r#"{"cmd":"fault","spec":"shaft.b=5@0"}"#;
    for host in [
        format!("evil.example:{port}"),
        "evil.example".into(),
        format!("127.0.0.1.evil.example:{port}"),
        format!("localhost.evil.example:{port}"),
        String::new(),
    ] {
        for (method, path, headers, body) in [
            (
                "POST",
                "/api/control",
                vec![
                    "Content-Type: application/json".to_string(),
                    format!("Origin: http://{host}"),
                ],
                fault,
            ),
            ("GET", "/api/events", vec![], ""),
            ("GET", "/api/status", vec![], ""),
            ("GET", "/", vec![], ""),
            ("GET", "/assets/panel.js", vec![], ""),
        ] {
            let h: Vec<&str> = headers.iter().map(String::as_str).collect();
            let (code, text) = http_to(live.addr, &host, method, path, &h, body);
            assert_eq!(code, 421, "Host {host:?}: {method} {path}: {text}");
        }
    }
    for host in [
        format!("127.0.0.1:{port}"),
        format!("localhost:{port}"),
        format!("LOCALHOST.:{port}"),
        format!("[::1]:{port}"),
        "cell-7.lab.example".into(),
    ] {
        let (code, text) = http_to(live.addr, &host, "GET", "/api/status", &[], "");
        assert_eq!(code, 200, "Host {host}: {text}");
    }
    // The right Host with a foreign Origin: refused too.
    let (code, text) = http(
        live.addr,
        "POST",
        "/api/control",
        &[
            "Content-Type: application/json",
            "Origin: http://evil.example",
        ],
        fault,
    );
    assert_eq!(code, 403, "{text}");
    // What an error quotes of a message is capped; a huge message is refused unread.
    let long = format!(r#"{{"cmd":"fault","spec":"{}"}}"#, "x".repeat(10_000));
    let (code, reply) = post(live.addr, "/api/control", &long);
    assert_eq!(code, 400);
    let error = reply["error"].as_str().unwrap();
    assert!(error.len() < 500 && error.contains("bytes)"), "{error}");
    let huge = format!(r#"{{"cmd":"fault","spec":"{}"}}"#, "x".repeat(1 << 20));
    assert_eq!(post(live.addr, "/api/control", &huge).0, 413);
    let mut sse = Sse::connect(live.addr, "/api/events");
    let refused = sse.until(30, |e| e["type"] == "error");
    let message = refused.last().unwrap().1["message"]
        .as_str()
        .unwrap()
        .to_string();
    assert!(message.len() < 500, "{} bytes", message.len());
    drop(live);

    // --bind takes a name; requests may name it.
    let named = Live::start(&["--bind", "localhost", "--duration", "60"]);
    assert!(named.addr.ip().is_loopback(), "{}", named.url);
    let host = format!("localhost:{}", named.addr.port());
    assert_eq!(
        http_to(named.addr, &host, "GET", "/api/status", &[], "").0,
        200
    );
    drop(named);

    // The token from the environment or a file: in force, and not on the command line.
    let s = physid_testkit::Scratch::new("physid-token");
    let file = s.file("token");
    std::fs::write(&file, "from-a-file-token\n").unwrap();
    for (args, env, token) in [
        (
            vec!["--token-file", file.to_str().unwrap()],
            None,
            "from-a-file-token",
        ),
        (vec![], Some("from-the-environment"), "from-the-environment"),
    ] {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_physid"));
        cmd.args(["live", "--duration", "60", "--port", "0"])
            .args(&args);
        if let Some(t) = env {
            cmd.env("PHYSID_TOKEN", t);
        }
        let mut child = cmd
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let url = line.trim().strip_prefix("physid live: panel at ").unwrap();
        let addr: SocketAddr = url[7..].split('/').next().unwrap().parse().unwrap();
        assert_eq!(http(addr, "GET", "/api/status", &[], "").0, 401, "{args:?}");
        let path = format!("/api/status?token={token}");
        assert_eq!(http(addr, "GET", &path, &[], "").0, 200, "{args:?}");
        let cmdline = std::fs::read(format!("/proc/{}/cmdline", child.id())).unwrap();
        assert!(!String::from_utf8_lossy(&cmdline).contains(token));
        let _ = child.kill();
        let _ = child.wait();
    }
    // A token file that never ends (a wrong path: /dev/zero) is refused at 64 KiB, not read
    // until the memory is gone.
    let o = Command::new(env!("CARGO_BIN_EXE_physid"))
        .args(["live", "--duration", "1", "--port", "0"])
        .args(["--token-file", "/dev/zero"])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.code() == Some(1) && e.contains("--token-file /dev/zero: longer than 65536 bytes"),
        "{e}"
    );
}

// ---- the real browser ----

/// Headless Chromium opens the panel on the virtual cell, sees the traces and the cyclic view
/// fill, injects a shaft-stiffness fault through the page's control and sees the K alarm within
/// 2 s of simulated time after the fault — and no B alarm — then acknowledges it. The page is
/// photographed (`docs/live-panel.png` when `PHYSID_UPDATE_DOCS=1`).
#[test]
fn the_panel_in_a_real_browser() {
    // Long enough that the fault is clicked before the end while the other browser test
    // loads the machine too.
    let live = Live::start(&[
        "--scenario",
        "shaft-steady",
        "--duration",
        "40",
        "--pace",
        "2",
    ]);
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let Some(browser) = common::Browser::start("1500,1250").await else {
            return;
        };
        let c = browser.client.clone();
        c.goto(&live.url).await.unwrap();
        let js = |expr: &'static str| browser.js(expr);
        let wait = |expr: &'static str, secs: u64| browser.wait(expr, secs);
        // The traces and the cyclic view receive data, drawn by uPlot.
        wait("window.physid.tracePoints > 200 && window.physid.cycles > 5 && window.physid.t > 3", 40).await;
        assert_eq!(js("window.physid.alarms").await, json!(0), "no alarm while healthy");
        assert_eq!(js("document.querySelectorAll('#plot-pcyl canvas').length > 0").await, json!(true));
        assert_eq!(js("window.physid.last.cycle.curve.p_cyl.length").await, json!(360));
        // No friction characterisation or combustion analysis on this run: their cards stay
        // hidden.
        assert_eq!(js("document.getElementById('friction-card').hidden").await, json!(true));
        assert_eq!(js("document.getElementById('combustion-card').hidden").await, json!(true));
        // Inject the stiffness fault through the page.
        let t_click = js("window.physid.t").await.as_f64().unwrap();
        c.find(Locator::Id("fault-spec"))
            .await
            .unwrap()
            .send_keys("shaft.k=1000")
            .await
            .unwrap();
        c.find(Locator::Id("fault-btn")).await.unwrap().click().await.unwrap();
        wait("document.getElementById('reply').textContent.includes('fault: done')", 10).await;
        // The cell's time when the fault went in (its control event): the click's page time may
        // be earlier on a loaded machine.
        wait("window.physid.last.control && window.physid.last.control.cmd === 'fault'", 10).await;
        let t_fault = js("window.physid.last.control.t_s").await.as_f64().unwrap();
        assert!(t_fault >= t_click, "{t_fault} {t_click}");
        wait("document.querySelector('#alarms tr[data-param=\"K\"]') !== null", 30).await;
        let alarm = js("window.physid.first.alarm").await;
        let dt = alarm["t_s"].as_f64().unwrap() - t_fault;
        eprintln!("K alarm {dt:.3} s of simulated time after the fault (injected at {t_fault:.3} s, clicked at {t_click:.3} s)");
        assert!(dt > 0.0 && dt <= 2.0, "K alarm {dt} s after the fault");
        // To the end of the run: no B alarm.
        wait("window.physid.state === 'ended'", 60).await;
        assert_eq!(
            js("document.querySelectorAll('#alarms tr[data-param=\"B\"]').length").await,
            json!(0)
        );
        // Acknowledge the first K alarm.
        c.find(Locator::Css("#alarms button.ack")).await.unwrap().click().await.unwrap();
        wait("document.querySelectorAll('#alarms tr.acked').length === 1", 10).await;
        let png = c.screenshot().await.unwrap();
        let shot = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("live-panel.png");
        std::fs::write(&shot, &png).unwrap();
        if std::env::var_os("PHYSID_UPDATE_DOCS").is_some() {
            let docs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/live-panel.png");
            std::fs::write(docs, &png).unwrap();
        }
        // A motored engine with the friction characterisation: the page shows the chosen
        // coefficients (estimated and frozen) and the cycle means against their predictions.
        let friction = Live::start(&[
            "--scenario",
            "friction-sweep",
            "--duration",
            "8",
            "--pace",
            "max",
            "--friction",
            "cell",
            "--friction-after",
            "20",
        ]);
        c.goto(&friction.url).await.unwrap();
        wait("window.physid.state === 'ended' && window.physid.frictionCycles > 20", 40).await;
        let chosen = js("window.physid.identifiability.friction").await;
        let estimable = chosen["estimable"].as_array().unwrap().len();
        assert!(estimable > 0 && estimable + chosen["frozen"].as_array().unwrap().len() == 20);
        assert_eq!(
            js("document.querySelectorAll('#ident span.param.estimable').length").await,
            json!(estimable)
        );
        assert_eq!(js("document.getElementById('friction-card').hidden").await, json!(false));
        assert_eq!(js("document.querySelectorAll('#plot-friction canvas').length > 0").await, json!(true));
        let png = c.screenshot().await.unwrap();
        std::fs::write(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("live-panel-friction.png"), &png).unwrap();
        // The fired engine with the combustion analysis: the IMEP and MFB50 trend per cycle and
        // the CoV of IMEP over the fired cycles, as the events say.
        let fired = Live::start(&[
            "--scenario",
            "fired-steady",
            "--duration",
            "2",
            "--pace",
            "max",
            "--combustion",
            "--step-deg",
            "0.5",
        ]);
        c.goto(&fired.url).await.unwrap();
        wait("window.physid.state === 'ended' && window.physid.combustionCycles > 10", 40).await;
        assert_eq!(js("document.getElementById('combustion-card').hidden").await, json!(false));
        assert_eq!(js("document.querySelectorAll('#plot-combustion canvas').length > 0").await, json!(true));
        let last = js("window.physid.last.combustion").await;
        assert_eq!(last["figures"]["fired"].as_f64(), Some(1.0), "{last}");
        let mfb50 = last["figures"]["mfb50_deg"].as_f64().unwrap();
        assert!((0.0..20.0).contains(&mfb50), "{last}");
        // A steady fired engine without cycle-to-cycle variation: a CoV of IMEP near zero.
        let cov = js("window.physid.covImep").await.as_f64().unwrap();
        assert!((0.0..0.01).contains(&cov), "CoV {cov}");
        let shown = js("document.getElementById('cov-imep').textContent").await;
        assert!(shown.as_str().unwrap().starts_with("CoV of IMEP "), "{shown}");
        // The latest cycle's pressure and heat release rate: drawn from −360° ATDC, the rate's
        // peak within the cell's burn (Wiebe from −15° over 50°), none outside the window.
        let hrr = js("(() => { const d = window.physid.uplot('plot-hrr').data;              let k = 0; d[2].forEach((v, i) => { if (v !== null && v > d[2][k]) k = i; });              return { n: d[0].length, x0: d[0][0], peak: d[2][k], at: d[0][k],              outside: d[2].filter((v, i) => v !== null && (d[0][i] < -90 || d[0][i] > 120)).length,              pmax: Math.max(...d[1].filter((v) => v !== null)) }; })()")
        .await;
        assert_eq!(hrr["x0"].as_f64(), Some(-360.0), "{hrr}");
        assert!(hrr["n"].as_u64().unwrap() >= 360, "{hrr}");
        assert!(hrr["peak"].as_f64().unwrap() > 0.0, "{hrr}");
        assert!((-15.0..35.0).contains(&hrr["at"].as_f64().unwrap()), "{hrr}");
        assert_eq!(hrr["outside"].as_u64(), Some(0), "{hrr}");
        assert!(hrr["pmax"].as_f64().unwrap() > 10.0, "{hrr} (bar)");
        js("document.getElementById('combustion-card').scrollIntoView() || true").await;
        let png = c.screenshot().await.unwrap();
        std::fs::write(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("live-panel-combustion.png"), &png).unwrap();
        // The cyclic-torque estimation: its chosen parameters and the estimates per cycle.
        let torque = Live::start(&[
            "--scenario",
            "torque-ramp",
            "--duration",
            "3",
            "--pace",
            "max",
            "--torque",
        ]);
        c.goto(&torque.url).await.unwrap();
        wait("window.physid.state === 'ended' && window.physid.torqueCycles > 5", 40).await;
        let chosen = js("window.physid.identifiability.torque").await;
        assert!(!chosen["estimable"].as_array().unwrap().is_empty(), "{chosen}");
        assert_eq!(
            js("document.querySelectorAll('#torque-table tr').length").await,
            json!(1 + chosen["estimable"].as_array().unwrap().len())
        );
        // The twin beside the cell (docs/twin.md): the reciprocating mass grows 12.5 % at
        // 2.5 s; the twin's card shows each channel's residual and each parameter against its
        // calibrated value, the chosen channel measured against the twin (window means, within
        // 1 % of each other), and the alarm names engine.m_rec.
        let dir = physid_testkit::Scratch::new("physid-panel-twin");
        let cell = dir.file("cell.toml");
        std::fs::write(&cell, "name = \"twin\"\nduration = 1.0\n[[speed]]\nt0 = 0.0\nt1 = 1.0\nkind = \"constant\"\nvalue = 1000.0\n[[throttle]]\nt0 = 0.0\nt1 = 1.0\nkind = \"constant\"\nvalue = 90.0\n").unwrap();
        let twin = Live::start(&[
            "--scenario",
            "shaft-steady",
            "--duration",
            "5",
            "--pace",
            "max",
            "--fault",
            "engine.m_rec=0.9@2.5",
            "--twin",
            cell.to_str().unwrap(),
        ]);
        c.goto(&twin.url).await.unwrap();
        wait("window.physid.state === 'ended' && window.physid.twinWindows > 50", 40).await;
        assert_eq!(js("document.getElementById('twin-card').hidden").await, json!(false));
        assert_eq!(js("document.querySelectorAll('#twin-residual tbody tr').length").await, json!(4));
        assert_eq!(js("document.querySelectorAll('#twin-params tbody tr').length").await, json!(4));
        let row = js("Array.from(document.querySelectorAll('#twin-params tbody tr')).map((r) => r.textContent).join(' | ')").await;
        assert!(row.as_str().unwrap().contains("engine.m_rec0.9"), "{row}");
        let alarm = js("Array.from(document.querySelectorAll('#alarms tbody tr')).map((r) => r.cells[1].textContent)").await;
        assert_eq!(alarm, json!(["engine.m_rec"]), "{alarm}");
        assert_eq!(
            js("Array.from(document.querySelectorAll('#twin-channel option')).map((o) => o.textContent)").await,
            json!(["omega_dy", "omega_en", "p_int", "torque_shaft"])
        );
        // The engine's speed, measured and the twin's: drawn, and close.
        let close = "(() => { const d = window.physid.uplot('plot-twin').data; if (d.length !== 3 || d[0].length < 50) return false; \
            return d[1].every((m, i) => Math.abs(m - d[2][i]) < 0.01 * Math.abs(m)); })()";
        wait(close, 10).await;
        // Another channel chosen: its trend.
        js("(() => { const s = document.getElementById('twin-channel'); s.value = 'p_int'; s.dispatchEvent(new Event('change')); return true; })()").await;
        wait("(() => { const d = window.physid.uplot('plot-twin').data; return d[1].length > 50 && d[1][0] > 5e4; })()", 10).await;
        js("document.getElementById('twin-card').scrollIntoView() || true").await;
        let png = c.screenshot().await.unwrap();
        std::fs::write(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("live-panel-twin.png"), &png).unwrap();
        c.close().await.unwrap();
    });
}

/// The operator's view in a real Chromium (issue 40, items 1, 3 and 4): a page of a rebound
/// name cannot reach the panel; an empty speed field sends nothing; a fault shows when it was
/// stamped and when it arrived; an alarm raises the banner and a mark on the K plot, and the
/// banner acknowledges it; the traces are envelopes, p_int and throttle have their own axes, the
/// cyclic view is centred on firing TDC; a card whose data stop says "stale since"; a stage
/// restarts from its button; the layout comes from `--layout FILE`, changes on the page and
/// survives a reload; the help opens with `?`; the events export; Stop asks first.
#[test]
fn the_operators_view_in_a_real_browser() {
    let s = physid_testkit::Scratch::new("physid-operator");
    let layout_file = s.file("layout.json");
    // Everything but the engine-torque cycle view; a 5 s window.
    std::fs::write(
        &layout_file,
        r#"{"plots": {"k": ["K"], "b": ["B"], "speed": ["omega_en", "omega_dy"],
            "torque": ["torque_shaft", "torque_engine"], "pint": ["p_int", "throttle"],
            "cycles": ["torque_engine", "torque_shaft"], "pcyl": ["p_cyl"],
            "friction": ["measured", "predicted", "nominal", "truth"]}, "window_s": 5}"#,
    )
    .unwrap();
    let live = Live::start(&[
        "--scenario",
        "shaft-steady",
        "--duration",
        "300",
        "--pace",
        "2",
        "--layout",
        layout_file.to_str().unwrap(),
    ]);
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let Some(browser) = common::Browser::start("1500,1400").await else {
            return;
        };
        let c = browser.client.clone();
        let js = |expr: &'static str| browser.js(expr);
        let wait = |expr: &'static str, secs: u64| browser.wait(expr, secs);
        let click = |id: &'static str| {
            let c = c.clone();
            async move { c.find(Locator::Id(id)).await.unwrap().click().await.unwrap() }
        };

        // 1. A page whose name was rebound to this machine gets nothing from the panel, and
        // its script cannot post a control.
        let port = live.addr.port();
        c.goto(&format!("http://{}:{port}/", common::REBIND_HOST)).await.unwrap();
        let body = js("document.body.innerText").await;
        assert!(body.as_str().unwrap().contains("refused"), "{body}");
        let status = c
            .execute_async(
                "const done = arguments[0]; fetch('/api/control', {method: 'POST', headers: \
                 {'Content-Type': 'application/json'}, body: JSON.stringify({cmd: 'fault', \
                 spec: 'shaft.b=5@0'})}).then(r => done(r.status), e => done(String(e)));",
                vec![],
            )
            .await
            .unwrap();
        assert_eq!(status, json!(421));

        // The panel itself, with the layout file's plots and window.
        c.goto(&live.url).await.unwrap();
        wait("window.physid.tracePoints > 200 && window.physid.cycles > 5 && window.physid.t > 3", 40).await;
        assert_eq!(
            js("document.getElementById('log').textContent.includes('fault')").await,
            json!(false),
            "the rebound page's fault reached the cell"
        );
        // The page's plots are the server's (a --layout file is checked against these).
        let page_plots = js("window.physid.plots").await;
        let server: serde_json::Map<String, Value> = physid_live::layout::PLOTS
            .iter()
            .map(|(id, ch)| (id.to_string(), json!(ch)))
            .collect();
        assert_eq!(page_plots, Value::Object(server));
        assert_eq!(js("window.physid.layout.window_s").await, json!(5));
        assert_eq!(js("document.querySelector('.card[data-plot=tcyc]').hidden").await, json!(true));
        assert_eq!(js("document.querySelector('.card[data-plot=pcyl]').hidden").await, json!(false));
        // The header counts samples while the run goes.
        wait("Number(document.getElementById('samples').textContent) > 10000", 20).await;

        // 4. Envelopes (mean inside min–max), one axis per unit, the cyclic view centred on TDC.
        assert_eq!(
            js("(() => { const d = window.physid.uplot('plot-speed').data; if (d.length !== 7 || d[0].length < 50) return false; \
                return d[1].every((m, i) => m === null || (d[3][i] <= m + 1e-9 && m <= d[2][i] + 1e-9)); })()")
                .await,
            json!(true)
        );
        assert_eq!(
            js("[1, 4].map(i => window.physid.uplot('plot-pint').series[i].scale).join()").await,
            json!("kPa,deg")
        );
        let centred = js("(() => { const d = window.physid.uplot('plot-pcyl').data, x = d[0], p = d[d.length - 1]; \
            let k = 0; for (let i = 1; i < p.length; i++) if (p[i] > p[k]) k = i; return [x[0], x[x.length - 1], x[k]]; })()")
            .await;
        let (x0, x1, peak) = (
            centred[0].as_f64().unwrap(),
            centred[1].as_f64().unwrap(),
            centred[2].as_f64().unwrap(),
        );
        assert!(x0 == -360.0 && x1 < 360.0 && peak.abs() < 40.0, "{centred}");

        // 3. An empty speed field sends nothing and says why.
        click("speed").await;
        c.find(Locator::Css("#f-speed button")).await.unwrap().click().await.unwrap();
        wait("document.getElementById('reply').textContent.includes('nothing was sent')", 5).await;
        assert_eq!(js("window.physid.last.control === undefined").await, json!(true));

        // 4. A fault from the page: stamped with the page's time, and when it arrived.
        c.find(Locator::Id("fault-spec")).await.unwrap().send_keys("shaft.k=1000").await.unwrap();
        click("fault-btn").await;
        wait("document.getElementById('reply').textContent.includes('fault: done — acts at t =')", 10).await;
        wait("document.getElementById('log').textContent.includes('the cell was at t =')", 10).await;
        // The alarm: a banner, and a mark on the K plot at its time.
        wait("!document.getElementById('alarm-banner').hidden", 40).await;
        let banner = js("document.getElementById('alarm-text').textContent").await;
        assert!(banner.as_str().unwrap().starts_with("ALARM K: fell"), "{banner}");
        assert_eq!(js("window.physid.marks().some(m => m.param === 'K')").await, json!(true));
        // Acknowledged from the banner (every K alarm raised so far, bounded).
        for _ in 0..20 {
            if js("document.getElementById('alarm-banner').hidden").await == json!(true) {
                break;
            }
            click("alarm-ack").await;
            tokio::time::sleep(Duration::from_millis(300)).await;
        }
        assert_eq!(js("document.getElementById('alarm-banner').hidden").await, json!(true));

        // A stage restarts from its button.
        c.find(Locator::Css("button.restart[data-stage=shaft]")).await.unwrap().click().await.unwrap();
        wait("document.getElementById('reply').textContent === 'restart: done'", 10).await;

        // Help: the ? key opens it, Esc closes it.
        c.find(Locator::Css("body")).await.unwrap().send_keys("?").await.unwrap();
        wait("!document.getElementById('help').hidden", 5).await;
        c.find(Locator::Css("body")).await.unwrap().send_keys("\u{e00c}").await.unwrap();
        wait("document.getElementById('help').hidden", 5).await;

        // The layout: hide the cylinder-pressure view on the page; a reload keeps it hidden.
        c.find(Locator::Css("#layout-picker input[data-plot=pcyl]")).await.unwrap().click().await.unwrap();
        wait("document.querySelector('.card[data-plot=pcyl]').hidden", 5).await;
        c.refresh().await.unwrap();
        wait("window.physid.layout !== null && window.physid.tracePoints > 0", 20).await;
        assert_eq!(js("document.querySelector('.card[data-plot=pcyl]').hidden").await, json!(true));
        click("layout-reset").await;
        wait("!document.querySelector('.card[data-plot=pcyl]').hidden", 5).await;

        // 3. The engine stops (torque demand, no speed): the cycles stop, their cards say so.
        click("mode-torque").await;
        c.find(Locator::Id("speed")).await.unwrap().send_keys("0").await.unwrap();
        c.find(Locator::Css("#f-speed button")).await.unwrap().click().await.unwrap();
        wait("document.querySelector('.card[data-feed=cycle]').classList.contains('stale')", 60).await;
        let tag = js("document.querySelector('.card[data-feed=cycle] .stale-tag').textContent").await;
        assert!(tag.as_str().unwrap().starts_with("stale since t = "), "{tag}");
        // The estimates go on (held at a standstill): not stale.
        assert_eq!(
            js("document.querySelector('.card[data-feed=estimate]').classList.contains('stale')").await,
            json!(false)
        );

        // The session's events export (what the page's buttons download).
        // Both at once: the run goes on between two calls.
        let both = js("[window.physidExport.ndjson(), window.physidExport.csv()]").await;
        let lines: Vec<Value> = both[0]
            .as_str()
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert!(lines.iter().any(|e| e["type"] == "alarm" && e["param"] == "K"));
        assert!(lines.iter().any(|e| e["type"] == "control" && e["cmd"] == "restart"));
        assert!(lines.iter().all(|e| e["seq"].is_u64() && e["type"] != "trace"));
        let csv = both[1].as_str().unwrap();
        assert!(csv.starts_with("seq,type,t_s,summary,event\n"));
        assert_eq!(csv.lines().count(), lines.len() + 1);

        // Stop asks first: Cancel keeps the run, then Stop the run ends it.
        click("stop").await;
        assert_eq!(js("document.getElementById('stop-confirm').hidden").await, json!(false));
        click("stop-no").await;
        tokio::time::sleep(Duration::from_millis(500)).await;
        assert_eq!(js("window.physid.state").await, json!("running"));
        click("stop").await;
        click("stop-yes").await;
        wait("window.physid.state === 'ended'", 20).await;
        let png = c.screenshot().await.unwrap();
        std::fs::write(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("live-operator.png"), &png).unwrap();
        c.close().await.unwrap();
    });
}

/// The logging control writes the live data as it comes: the file holds, for the stretch
/// recorded, exactly the samples `physid simulate` gives for the same scenario (every
/// channel, bit for bit); names that are not plain, taken names and a stop without a log are
/// refused by field.
#[test]
fn the_logging_control_writes_the_live_data() {
    let s = physid_testkit::Scratch::new("physid-panel-log");
    let dir = s.file("logs");
    let live = Live::start(&[
        "--scenario",
        "shaft-steady",
        "--duration",
        "10",
        "--pace",
        "3",
        "--log-dir",
        dir.to_str().unwrap(),
    ]);
    let mut sse = Sse::connect(live.addr, "/api/events");
    sse.until(30, |e| {
        e["type"] == "estimate" && e["t_s"].as_f64().unwrap() > 0.5
    });
    for (body, want) in [
        (r#"{"cmd":"record","file":"../up.parquet"}"#, "field 'file'"),
        (
            r#"{"cmd":"record","file":"run.csv"}"#,
            "ending in .parquet or .mf4",
        ),
        (r#"{"cmd":"record","stop":true}"#, "no log is being written"),
        (r#"{"cmd":"record"}"#, "field 'file'"),
    ] {
        let (code, reply) = post(live.addr, "/api/control", body);
        assert_eq!(code, 400, "{body}: {reply}");
        assert!(
            reply["error"].as_str().unwrap().contains(want),
            "{body}: {reply}"
        );
    }
    let (code, reply) = post(
        live.addr,
        "/api/control",
        r#"{"cmd":"record","file":"run-1.parquet"}"#,
    );
    assert_eq!((code, &reply["cmd"]), (200, &json!("record")), "{reply}");
    let (code, reply) = post(
        live.addr,
        "/api/control",
        r#"{"cmd":"record","file":"run-1.parquet"}"#,
    );
    assert_eq!(code, 400, "a log is open: {reply}");
    sse.until(30, |e| {
        e["type"] == "log" && e["samples"].as_u64().unwrap() > 10_000
    });
    let (code, _) = post(live.addr, "/api/control", r#"{"cmd":"record","stop":true}"#);
    assert_eq!(code, 200);
    let closed = sse.until(30, |e| e["type"] == "log" && e["state"] == "closed");
    let closed = &closed.last().unwrap().1;
    let file = dir.join("run-1.parquet");
    assert_eq!(closed["file"], file.display().to_string());
    assert_eq!(
        closed["bytes"].as_u64().unwrap(),
        std::fs::metadata(&file).unwrap().len()
    );
    let logged = physid_io::read_parquet(&file, None).unwrap();
    assert_eq!(closed["samples"].as_u64().unwrap() as usize, logged.len());
    assert!(logged.len() > 5000, "{} samples", logged.len());
    // And to MDF4, which asammdf and MATLAB users open: the same samples, every channel —
    // taken while the run goes on (the comparisons after it).
    let (code, reply) = post(
        live.addr,
        "/api/control",
        r#"{"cmd":"record","file":"run-2.mf4"}"#,
    );
    assert_eq!(code, 200, "{reply}");
    sse.until(30, |e| {
        e["type"] == "log"
            && e["file"].as_str().unwrap().ends_with("run-2.mf4")
            && e["samples"].as_u64().unwrap() > 5_000
    });
    let (code, _) = post(live.addr, "/api/control", r#"{"cmd":"record","stop":true}"#);
    assert_eq!(code, 200);
    let closed2 = sse.until(30, |e| e["type"] == "log" && e["state"] == "closed");
    let closed2 = &closed2.last().unwrap().1;
    let file2 = dir.join("run-2.mf4");
    assert_eq!(
        closed2["bytes"].as_u64().unwrap(),
        std::fs::metadata(&file2).unwrap().len()
    );
    let logged2 = physid_io::read_mdf(&file2, None).unwrap();
    assert_eq!(closed2["samples"].as_u64().unwrap() as usize, logged2.len());
    // The same stretch of the same scenario, simulated.
    let sim = s.file("sim.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "10",
        "--recording",
        sim.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let sim = physid_io::read_parquet(&sim, None).unwrap();
    let same_as_simulated = |logged: &physid_core::Recording| {
        let t0 = logged.values("t").unwrap()[0];
        let k0 = sim
            .values("t")
            .unwrap()
            .iter()
            .position(|&t| t == t0)
            .expect("the first logged time in the simulation");
        for c in logged.channels() {
            let want = &sim.values(&c.name).unwrap()[k0..k0 + logged.len()];
            assert!(c.values == want, "channel {} differs", c.name);
            assert_eq!(c.unit, sim.channel(&c.name).unwrap().unit, "{}", c.name);
        }
    };
    same_as_simulated(&logged);
    assert_eq!(logged2.channels().len(), sim.channels().len());
    same_as_simulated(&logged2);
}

/// A layout file naming a plot the panel does not have is refused before anything listens,
/// naming the file and the plots there are.
#[test]
fn a_layout_file_that_does_not_fit_is_refused() {
    let s = physid_testkit::Scratch::new("physid-layout");
    let file = s.file("layout.json");
    std::fs::write(&file, r#"{"plots": {"speeds": ["omega_en"]}}"#).unwrap();
    let o = physid(&[
        "live",
        "--scenario",
        "shaft-steady",
        "--port",
        "0",
        "--layout",
        file.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("layout.json: no plot 'speeds'; the panel's plots: k, b, speed"),
        "{err}"
    );
    let missing = physid(&[
        "live",
        "--port",
        "0",
        "--layout",
        "/nonexistent/layout.json",
    ]);
    assert!(String::from_utf8_lossy(&missing.stderr).contains("--layout /nonexistent/layout.json"));
}
