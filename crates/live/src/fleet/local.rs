//! A local `nats-server` with JetStream for the fleet's tests and `physid bench fleet`: on
//! 127.0.0.1, a free port, file storage in a temporary directory, the monitoring endpoint on a
//! second free port; killed (and its store removed) when dropped.

use super::FleetError;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Where Debian and others install `nats-server`, then `PATH`.
pub fn nats_server_bin() -> Option<PathBuf> {
    let fixed = [
        "/usr/sbin/nats-server",
        "/usr/bin/nats-server",
        "/usr/local/bin/nats-server",
    ]
    .iter()
    .map(PathBuf::from);
    let on_path = std::env::var_os("PATH")
        .map(|p| {
            std::env::split_paths(&p)
                .map(|d| d.join("nats-server"))
                .collect::<Vec<_>>()
        })
        .unwrap_or_default();
    fixed.chain(on_path).find(|p| p.is_file())
}

fn free_port() -> Result<u16, FleetError> {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .map_err(|e| FleetError::Invalid(format!("finding a free loopback port: {e}")))
}

/// A running local server.
pub struct LocalServer {
    /// The client port.
    pub port: u16,
    /// The monitoring port (`/varz`: messages and bytes in and out).
    pub monitor_port: u16,
    dir: tempfile::TempDir,
    args: Vec<String>,
    child: Option<Child>,
}

impl LocalServer {
    /// Start one with `extra` arguments (e.g. `--user U --pass P`, `--auth TOKEN`).
    pub fn start(extra: &[&str]) -> Result<Self, FleetError> {
        let dir = tempfile::Builder::new()
            .prefix("physid-nats-")
            .tempdir()
            .map_err(|e| FleetError::Invalid(format!("a store directory: {e}")))?;
        let mut s = Self {
            port: free_port()?,
            monitor_port: free_port()?,
            dir,
            args: extra.iter().map(|s| s.to_string()).collect(),
            child: None,
        };
        s.spawn()?;
        Ok(s)
    }

    /// The store directory.
    pub fn dir(&self) -> &Path {
        self.dir.path()
    }

    fn spawn(&mut self) -> Result<(), FleetError> {
        let bin = nats_server_bin().ok_or_else(|| {
            FleetError::Invalid(
                "nats-server is not installed (Debian: apt-get install nats-server)".into(),
            )
        })?;
        let child = Command::new(&bin)
            .args(["-js", "-a", "127.0.0.1", "-p", &self.port.to_string()])
            .args(["-m", &self.monitor_port.to_string(), "-sd"])
            .arg(self.dir.path())
            .args(&self.args)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| FleetError::Invalid(format!("starting {}: {e}", bin.display())))?;
        self.child = Some(child);
        let deadline = Instant::now() + Duration::from_secs(10);
        while std::net::TcpStream::connect(("127.0.0.1", self.port)).is_err() {
            if Instant::now() > deadline {
                return Err(FleetError::Invalid(format!(
                    "nats-server did not listen on 127.0.0.1:{} within 10 s",
                    self.port
                )));
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        Ok(())
    }

    /// Kill it (SIGKILL), wait `down`, start it again on the same port and store.
    pub fn restart(&mut self, down: Duration) -> Result<(), FleetError> {
        self.kill();
        std::thread::sleep(down);
        self.spawn()
    }

    fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    /// `nats://USERINFO127.0.0.1:PORT` (`userinfo`: `""`, `"user:pass@"` or `"token@"`).
    pub fn url(&self, userinfo: &str) -> String {
        format!("nats://{userinfo}127.0.0.1:{}", self.port)
    }

    /// The server's process id, while it runs.
    pub fn pid(&self) -> Option<u32> {
        self.child.as_ref().map(Child::id)
    }

    /// The server's counters from its monitoring endpoint (`/varz`).
    pub fn varz(&self) -> Result<serde_json::Value, FleetError> {
        use std::io::{Read, Write};
        let bad = |e: String| FleetError::Invalid(format!("nats-server /varz: {e}"));
        let mut s = std::net::TcpStream::connect(("127.0.0.1", self.monitor_port))
            .map_err(|e| bad(e.to_string()))?;
        s.set_read_timeout(Some(Duration::from_secs(5)))
            .map_err(|e| bad(e.to_string()))?;
        write!(
            s,
            "GET /varz HTTP/1.0\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n"
        )
        .map_err(|e| bad(e.to_string()))?;
        let mut text = String::new();
        s.read_to_string(&mut text)
            .map_err(|e| bad(e.to_string()))?;
        let body = text
            .split_once("\r\n\r\n")
            .map(|(_, b)| b)
            .ok_or_else(|| bad("no body".into()))?;
        serde_json::from_str(body).map_err(|e| bad(e.to_string()))
    }
}

impl Drop for LocalServer {
    fn drop(&mut self) {
        self.kill();
    }
}
