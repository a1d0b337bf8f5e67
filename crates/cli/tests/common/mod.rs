//! What the end-to-end test files share: running the `physid` binary under test.
#![allow(dead_code)]

use std::process::{Command, Output};

/// `physid simulate --scenario SCENARIO --duration SECONDS --recording PATH`, which must
/// succeed: a recording for a test to read.
pub fn simulated(path: &std::path::Path, scenario: &str, seconds: &str) {
    let o = physid(&[
        "simulate",
        "--scenario",
        scenario,
        "--duration",
        seconds,
        "--recording",
        path.to_str().unwrap_or_default(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Write `value` into `column` of `samples` of a CSV recording written by physid (a header,
/// a units row, then the samples).
pub fn set_cells(
    file: &std::path::Path,
    column: &str,
    samples: std::ops::Range<usize>,
    value: &str,
) {
    let text = std::fs::read_to_string(file).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let col = lines[0].split(',').position(|c| c == column).unwrap();
    for line in &mut lines[samples.start + 2..samples.end + 2] {
        let mut cells: Vec<String> = line.split(',').map(String::from).collect();
        cells[col] = value.into();
        *line = cells.join(",");
    }
    std::fs::write(file, lines.join("\n") + "\n").unwrap();
}

/// `physid-signal`'s golden 60−3 inductive-pickup recording written to `dat` as a lab's text
/// file: tab-separated, no header, volts and seconds in scientific notation; columns t, enc,
/// p_cyl and the true angle [rad]; `enc` is `nan` at the samples `dropouts`. Returns `dat`.
pub fn raw_wheel_dat(
    dat: &std::path::Path,
    dropouts: &[std::ops::Range<usize>],
) -> std::path::PathBuf {
    let golden = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../signal/tests/golden/wheel_vr_60m3.parquet");
    let rec = physid_io::read(&golden, &physid_io::ReadOptions::default()).unwrap();
    let mut text = String::new();
    let col = |n: &str| rec.values(n).unwrap();
    let (t, enc, p, truth) = (col("t"), col("enc"), col("p_cyl"), col("theta_true"));
    for i in 0..rec.len() {
        // Counts to volts (0.2 mV and 1 mV), the true angle from µrad to rad.
        let enc = if dropouts.iter().any(|r| r.contains(&i)) {
            "nan".to_string()
        } else {
            format!("{:.6e}", enc[i] * 2e-4)
        };
        text.push_str(&format!(
            "{:.6e}\t{enc}\t{:.6e}\t{:.9e}\n",
            t[i],
            p[i] * 1e-3,
            truth[i] * 1e-6
        ));
    }
    std::fs::write(dat, text).unwrap();
    dat.to_path_buf()
}

/// A crank-angle file `deg` decoded from one of `physid-signal`'s golden encoders: at every 0°
/// and 360° of its grid, over at least `revolutions`, the true angle (its `theta_true` in
/// µrad) modulo a revolution is `at` [deg] within `within` [deg].
pub fn revolutions_start_at(deg: &std::path::Path, at: f64, within: f64, revolutions: usize) {
    let r = physid_io::read(deg, &physid_io::ReadOptions::default()).unwrap();
    let (crank, truth) = (
        r.values("crank_deg").unwrap(),
        r.values("theta_true").unwrap(),
    );
    let starts: Vec<f64> = (0..r.len())
        .filter(|&i| crank[i] == 0.0 || crank[i] == 360.0)
        .map(|i| (truth[i] * 1e-6).to_degrees().rem_euclid(360.0))
        .collect();
    assert!(starts.len() >= revolutions, "{starts:?}");
    for a in &starts {
        assert!((a - at).abs() < within, "{starts:?}");
    }
}

/// Run the `physid` binary built for these tests with `args`.
pub fn physid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_physid"))
        .args(args)
        .output()
        .expect("run physid")
}

/// Run `physid` with `args`, which must succeed, and parse what it prints as JSON.
pub fn ok_json(args: &[&str]) -> serde_json::Value {
    let o = physid(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).expect("JSON on stdout")
}

/// Run `physid ARGS` (a shell word list) on a pseudo-terminal made by `script` (util-linux),
/// progress shown at once; what the terminal showed, stdout and stderr together.
pub fn on_a_terminal(args: &str) -> String {
    let cmd = format!(
        "PHYSID_PROGRESS_AFTER_MS=0 {} {args}",
        env!("CARGO_BIN_EXE_physid")
    );
    let o = Command::new("script")
        .args(["-qec", &cmd, "/dev/null"])
        .output()
        .expect("script (util-linux) runs a command on a pseudo-terminal");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Where a program is on PATH.
pub fn which(names: &[&str]) -> Option<std::path::PathBuf> {
    let path = std::env::var_os("PATH")?;
    names.iter().find_map(|n| {
        std::env::split_paths(&path)
            .map(|d| d.join(n))
            .find(|p| p.is_file())
    })
}

/// A host name the test browser resolves to 127.0.0.1, as a DNS rebinding attack's would.
pub const REBIND_HOST: &str = "rebind.example";

/// Headless Chromium driven over WebDriver (chromedriver on a free loopback port, killed when
/// dropped).
pub struct Browser {
    driver: std::process::Child,
    /// The WebDriver session.
    pub client: fantoccini::Client,
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.driver.kill();
        let _ = self.driver.wait();
    }
}

impl Browser {
    /// A session with a window of `size` ("W,H"); `None` when Chromium or chromedriver is not
    /// installed (and not on CI, where they must be: `.ci/run` installs them).
    pub async fn start(size: &str) -> Option<Self> {
        let (Some(driver), Some(browser)) = (
            which(&["chromedriver"]),
            which(&["chromium", "chromium-browser", "google-chrome"]),
        ) else {
            assert!(
                std::env::var_os("CI").is_none(),
                "CI needs chromium and chromedriver (apt-get install chromium chromium-driver)"
            );
            eprintln!("SKIPPED: chromium or chromedriver not installed");
            return None;
        };
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let driver = std::process::Command::new(driver)
            .args([format!("--port={port}"), "--allowed-ips=127.0.0.1".into()])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("start chromedriver");
        let mut caps = serde_json::Map::new();
        caps.insert(
            "goog:chromeOptions".into(),
            serde_json::json!({
                "binary": browser,
                "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", format!("--window-size={size}"),
                    // A DNS rebinding attacker's name that resolves to this machine (the panel's
                    // Host rule is tested from a page of that name).
                    format!("--host-resolver-rules=MAP {REBIND_HOST} 127.0.0.1")],
            }),
        );
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(20);
        let client = loop {
            match fantoccini::ClientBuilder::new(
                hyper_util::client::legacy::connect::HttpConnector::new(),
            )
            .capabilities(caps.clone())
            .connect(&format!("http://127.0.0.1:{port}"))
            .await
            {
                Ok(c) => break c,
                Err(e) if std::time::Instant::now() > deadline => panic!("chromedriver: {e}"),
                Err(_) => tokio::time::sleep(std::time::Duration::from_millis(200)).await,
            }
        };
        Some(Self { driver, client })
    }

    /// The value of the JavaScript expression `expr` in the page.
    pub async fn js(&self, expr: &str) -> serde_json::Value {
        self.client
            .execute(&format!("return {expr};"), vec![])
            .await
            .unwrap()
    }

    /// Wait (at most `secs`) until `expr` is true in the page.
    pub async fn wait(&self, expr: &str, secs: u64) {
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(secs);
        loop {
            if self.js(expr).await == serde_json::json!(true) {
                return;
            }
            if std::time::Instant::now() >= deadline {
                // What the page said last (a panel's reply line), to tell why.
                let said = self
                    .js("document.getElementById('reply') ? document.getElementById('reply').textContent : null")
                    .await;
                panic!("the page never had {expr} (its reply line: {said})");
            }
            tokio::time::sleep(std::time::Duration::from_millis(100)).await;
        }
    }
}
