//! The autopilot drivers against the real SITL builds: the telemetry port the bridge would
//! open carries the autopilot's MAVLink, the truth port answers, and a SITL that dies is an
//! error naming it with the end of its log.
//!
//! The builds are looked up in `ARDUPILOT_SITL` / `PX4_SITL` (folders), else in `../shared/`
//! next to the checkout. Without one a test says so on stderr and does nothing, unless
//! `C2_REQUIRE_SITL=1` (CI sets it), where a missing build fails it.

use std::io::Read;
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use harness::driver::autopilot::{
    ArdupilotSitl, AutopilotError, AutopilotSpec, Px4Sitl, TruthPort,
};

fn shared(var: &str, folder: &str) -> Option<PathBuf> {
    let dir = std::env::var_os(var).map(PathBuf::from).unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../shared")
            .join(folder)
    });
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("C2_REQUIRE_SITL").is_ok_and(|v| v == "1") {
        panic!(
            "C2_REQUIRE_SITL=1 but no {folder} at {} (set {var})",
            dir.display()
        );
    }
    eprintln!("not run: no {folder} at {} (set {var})", dir.display());
    None
}

/// Reads `port` until a MAVLink 2 HEARTBEAT header (magic 0xFD, message id 0) shows.
fn saw_heartbeat(port: &mut dyn Read, within: Duration) -> bool {
    let deadline = Instant::now() + within;
    let mut seen = Vec::new();
    let mut buf = [0u8; 512];
    while Instant::now() < deadline {
        if let Ok(n) = port.read(&mut buf) {
            seen.extend_from_slice(&buf[..n]);
        }
        // FD len incompat compat seq sys comp msgid(3 bytes, 0 = HEARTBEAT)
        if seen
            .windows(10)
            .any(|w| w[0] == 0xFD && w[1] == 9 && w[7..10] == [0, 0, 0])
        {
            return true;
        }
    }
    false
}

#[test]
fn ardupilot_sitl_talks_on_its_telemetry_and_truth_ports_and_its_death_is_named() {
    let Some(dir) = shared("ARDUPILOT_SITL", "ardupilot-sitl") else {
        return;
    };
    let mut sitl = ArdupilotSitl::new(dir.join("arducopter"));
    sitl.defaults = Some(dir.join("copter.parm"));
    let spec = AutopilotSpec::ArdupilotSitl(sitl);
    let out = tempfile::tempdir().unwrap();
    let mut ap = spec.start("copter", out.path()).unwrap();
    let mut fc = serialport::new(ap.fc_port(), 57_600)
        .timeout(Duration::from_millis(200))
        .open_native()
        .unwrap();
    assert!(
        saw_heartbeat(&mut fc, Duration::from_secs(20)),
        "no HEARTBEAT on the telemetry port; log:\n{}",
        std::fs::read_to_string(ap.log_path().unwrap()).unwrap_or_default()
    );
    let Some(TruthPort::Tcp(addr)) = ap.truth() else {
        panic!("ArduPilot's truth is its SERIAL0 on TCP")
    };
    let mut truth = TcpStream::connect_timeout(&addr, Duration::from_secs(5)).unwrap();
    truth
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    assert!(
        saw_heartbeat(&mut truth, Duration::from_secs(10)),
        "no HEARTBEAT on {addr}"
    );
    ap.check_running().unwrap();

    // A crash mid-phase: the error names the autopilot, its exit and its log.
    let pid = rustix::process::Pid::from_raw(ap.pid().unwrap() as i32).unwrap();
    rustix::process::kill_process(pid, rustix::process::Signal::KILL).unwrap();
    let deadline = Instant::now() + Duration::from_secs(5);
    let err = loop {
        match ap.check_running() {
            Err(e) => break e,
            Ok(()) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(50)),
            Ok(()) => panic!("a killed SITL still reads as running"),
        }
    };
    let AutopilotError::Died {
        ref name, ref log, ..
    } = err
    else {
        panic!("{err}")
    };
    assert_eq!(name, "copter");
    assert_eq!(log, &out.path().join("copter-sitl.log"));
    let text = err.to_string();
    assert!(
        text.contains("copter died") && text.contains("signal"),
        "{text}"
    );
}

#[test]
fn px4_sitl_talks_on_its_telemetry_port() {
    let Some(root) = shared("PX4_SITL", "px4-sitl") else {
        return;
    };
    let spec = AutopilotSpec::Px4Sitl(Px4Sitl::new(root));
    // A relative output folder, as `rig run --out target/rig-report` gives: the SITL runs in
    // a folder of its own, where a relative path leads nowhere (PX4 exited 255).
    let out = tempfile::tempdir_in(".").unwrap();
    let relative = Path::new(".").join(out.path().file_name().unwrap());
    let mut ap = spec.start("px4", &relative).unwrap();
    let mut fc = serialport::new(ap.fc_port(), 57_600)
        .timeout(Duration::from_millis(200))
        .open_native()
        .unwrap();
    assert!(
        saw_heartbeat(&mut fc, Duration::from_secs(30)),
        "no HEARTBEAT on the telemetry port; log:\n{}",
        std::fs::read_to_string(ap.log_path().unwrap()).unwrap_or_default()
    );
    ap.check_running().unwrap();
    ap.stop(Duration::from_secs(5));
}

/// The "a SITL that dies mid-phase is an error naming it, with its log": a whole
/// session (bridge, radio, router, ground station, truth) behind a real ArduPilot, whose
/// SITL is killed while the ground station listens.
#[test]
fn a_sitl_that_dies_mid_session_ends_it_with_an_error_naming_it_and_its_log() {
    use harness::mavlora::rigfile::NamedRadio;
    use harness::mavlora::session::SessionDefaults;
    use harness::mavlora::sitl::session::SitlSession;
    use harness::mavlora::sitl::{Target, options};

    let Some(dir) = shared("ARDUPILOT_SITL", "ardupilot-sitl") else {
        return;
    };
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let defaults = SessionDefaults::for_repo(repo).expect("mavlora-bridge and -router built");
    let mut sitl = ArdupilotSitl::new(dir.join("arducopter"));
    sitl.defaults = Some(dir.join("copter.parm"));
    let target = Target {
        autopilot: "copter".into(),
        spec: AutopilotSpec::ArdupilotSitl(sitl),
        radio: NamedRadio {
            name: "sik-64k".into(),
            setup: harness_radio::RadioSetup::builtin("sik-64k").unwrap(),
        },
    };
    let out = tempfile::tempdir().unwrap();
    let args = ["--scenario", "telemetry", "--listen", "60"]
        .map(String::from)
        .to_vec();
    let session = SitlSession::start(options(
        &defaults,
        &target,
        out.path(),
        args,
        Duration::from_secs(90),
    ))
    .unwrap();
    let files = session.files();
    let sitl_log = out.path().join("copter-sitl.log");
    assert!(files.contains(&sitl_log), "{files:?}");
    let pid = rustix::process::Pid::from_raw(session.autopilot_pid().unwrap() as i32).unwrap();
    rustix::process::kill_process(pid, rustix::process::Signal::KILL).unwrap();
    let started = Instant::now();
    let err = session
        .finish()
        .err()
        .expect("a dead SITL is an error")
        .to_string();
    assert!(
        started.elapsed() < Duration::from_secs(10),
        "noticed after {:?}",
        started.elapsed()
    );
    assert!(err.contains("copter died"), "{err}");
    assert!(err.contains(&sitl_log.display().to_string()), "{err}");
    assert!(sitl_log.exists());
}
