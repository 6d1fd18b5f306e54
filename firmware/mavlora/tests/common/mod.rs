//! What the end-to-end tests share: the repository root, (from `testkit`) a child-process
//! guard and pty pairs, temp folders and free ports, a binary run to its end, the checks of a
//! status JSON file ([`status_json`]).
// Each test program uses its own part of this.
#![allow(dead_code, unused_imports)]

pub mod status_json;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{ChildStdout, Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

pub use testkit::{Guard, pty_pair};

/// The repository root, where `fixtures/` and `firmware/` are.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A folder of the test's own, `mavlora-<name>-<pid>` in the temp folder.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mavlora-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A local TCP (and, in practice, UDP) port nobody uses now.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Runs `bin` with `args` in `dir` until it exits (killed after 10 s): its exit code and
/// stderr (logging at `info`, no colours).
pub fn run(bin: &str, dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let mut child = Command::new(bin)
        .args(args)
        .current_dir(dir)
        .env("RUST_LOG", "info")
        .env("NO_COLOR", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while child.try_wait().unwrap().is_none() && Instant::now() < deadline {
        thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A local UDP port nobody uses now.
pub fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Writes a radio signing key (32 bytes of `byte`, as hex) to `dir/radio.key`, mode 600: the
/// programs refuse a key others may read.
pub fn radio_key(dir: &Path, byte: u8) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let key = dir.join("radio.key");
    std::fs::write(&key, format!("{byte:02x}").repeat(32)).unwrap();
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).unwrap();
    key
}

/// `fixtures/mavlora_fc.py` (pymavlink) playing the flight controller, started and ready.
pub struct FcFixture {
    /// Kills it when dropped.
    pub guard: Guard,
    /// The pty it serves, for the bridge's `--fc`.
    pub port: String,
    /// Its stdout after the ready line: it reports events there.
    pub out: BufReader<ChildStdout>,
}

impl FcFixture {
    /// Starts it with its summary written to `summary` and `args`, and waits for its ready
    /// line.
    pub fn start(summary: &Path, args: &[&str]) -> FcFixture {
        let mut guard = Guard(
            Some(
                Command::new("python3")
                    .arg(root().join("fixtures/mavlora_fc.py"))
                    .arg("--summary")
                    .arg(summary)
                    .args(args)
                    .stdout(Stdio::piped())
                    .spawn()
                    .expect("python3"),
            ),
            "fc fixture",
        );
        let mut out = BufReader::new(guard.0.as_mut().unwrap().stdout.take().unwrap());
        let mut line = String::new();
        out.read_line(&mut line).unwrap();
        let ready: serde_json::Value = serde_json::from_str(&line).unwrap_or_else(|e| {
            panic!("fc fixture did not start (pymavlink installed?): {e}: {line:?}")
        });
        let port = ready["port"].as_str().unwrap().to_owned();
        FcFixture { guard, port, out }
    }
}

/// The parameter values a frame on the bridge's radio carries: a `PARAM_VALUE`'s one, or the
/// values of the bridge's packed `MAVLORA_PARAM_VALUES`; none for anything else.
pub fn param_values(frame: &mavlora::wire::OwnedFrame) -> Vec<mavlora::param::ParamValue> {
    use mavlora::wire::ids;
    match frame.message_id() {
        ids::PARAM_VALUE => mavlora::param::ParamValue::from_payload(frame.payload())
            .into_iter()
            .collect(),
        ids::MAVLORA_PARAM_VALUES => match frame.decode::<mavlora::dialect::MavMessage>() {
            Ok(mavlora::dialect::MavMessage::MAVLORA_PARAM_VALUES(p)) => {
                mavlora::param::pack::unpack(&p).unwrap_or_default()
            }
            _ => Vec::new(),
        },
        _ => Vec::new(),
    }
}
