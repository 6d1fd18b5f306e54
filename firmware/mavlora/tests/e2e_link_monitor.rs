//! What an unmodified ground station sees of the link (SORA OSO#6: the remote pilot can
//! continuously monitor the C2 link): the real `mavlora-bridge` and `mavlora-router`, a
//! pymavlink flight controller (`fixtures/mavlora_fc.py`), a radio of two pty pairs whose
//! ground → air direction the test cuts for 12 s (a drone that cannot hear the ground while
//! the ground still hears it), and pymavlink as the ground station
//! (`fixtures/mavlora_linkwatch.py`): it must get `RADIO_STATUS` at >= 0.5 Hz while the
//! link is up, one "uplink lost/degraded" `STATUSTEXT` within 5 s of the cut and one
//! "restored" within 5 s of the link coming back. Needs `python3` with pymavlink 2.4.

mod common;
use common::{FcFixture, Guard, free_udp_port, radio_key, root};

use std::io::{BufRead, BufReader, Read, Write};

use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::Duration;

use serde_json::Value;
use serialport::{SerialPort, TTYPort};

/// Copies bytes one way unless `cut` is set (then they are lost, as in the air).
fn copy(mut from: TTYPort, mut to: TTYPort, stop: Arc<AtomicBool>, cut: Arc<AtomicBool>) {
    thread::spawn(move || {
        let mut buf = [0u8; 512];
        while !stop.load(Ordering::Relaxed) {
            if let Ok(n) = from.read(&mut buf)
                && n > 0
                && !cut.load(Ordering::Relaxed)
            {
                let _ = to.write_all(&buf[..n]);
            }
        }
    });
}

#[test]
fn pymavlink_ground_station_is_told_of_an_uplink_loss_and_its_end() {
    // The radio link is signed, as every shipped config has it.
    let dir = std::env::temp_dir().join(format!("mavlora-linkmon-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let key = radio_key(&dir, 0x5c);
    let FcFixture {
        guard: fc,
        port: fc_port,
        ..
    } = FcFixture::start(&dir.join("fc.json"), &[]);

    let (mut a_master, a_slave) = TTYPort::pair().expect("pty pair");
    let (mut b_master, b_slave) = TTYPort::pair().expect("pty pair");
    a_master.set_timeout(Duration::from_millis(20)).unwrap();
    b_master.set_timeout(Duration::from_millis(20)).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let never = Arc::new(AtomicBool::new(false));
    let uplink_cut = Arc::new(AtomicBool::new(false));
    let (a2, b2) = (
        a_master.try_clone_native().unwrap(),
        b_master.try_clone_native().unwrap(),
    );
    copy(a_master, b2, stop.clone(), never);
    copy(b_master, a2, stop.clone(), uplink_cut.clone());

    let udp_port = free_udp_port();
    // a 1 s keep-alive: a real-time test cannot wait for LoRa's 9 s
    let mut router = Guard(
        Some(
            Command::new(env!("CARGO_BIN_EXE_mavlora-router"))
                .args(["--radio", &b_slave.name().unwrap()])
                .args(["--udp", &format!("127.0.0.1:{udp_port}")])
                .args(["--udp-bind", "127.0.0.1:0", "--link-quality-period", "1"])
                .arg("--key")
                .arg(&key)
                .arg("--status-json")
                .arg(dir.join("router.status.jsonl"))
                .spawn()
                .unwrap(),
        ),
        "router",
    );
    let mut bridge = Guard(
        Some(
            Command::new(env!("CARGO_BIN_EXE_mavlora-bridge"))
                .args(["--fc", &fc_port, "--radio", &a_slave.name().unwrap()])
                .arg("--profile")
                .arg(root().join("firmware/mavlora/profiles/px4-normal.toml"))
                .args(["--link-quality-period", "1"])
                .arg("--key")
                .arg(&key)
                .spawn()
                .unwrap(),
        ),
        "bridge",
    );

    let mut gcs = Command::new("python3")
        .arg(root().join("fixtures/mavlora_linkwatch.py"))
        .args(["--udp", &format!("127.0.0.1:{udp_port}"), "--listen", "34"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // The script's times count from its "ready" line; so do ours.
    let mut gcs_out = BufReader::new(gcs.stdout.take().unwrap());
    let mut ready = String::new();
    gcs_out.read_line(&mut ready).unwrap();
    assert!(ready.contains("ready"), "ground station: {ready}");
    let (cut_at, back_at) = (12.0, 24.0);
    thread::sleep(Duration::from_secs_f64(cut_at));
    uplink_cut.store(true, Ordering::Relaxed);
    thread::sleep(Duration::from_secs_f64(back_at - cut_at));
    uplink_cut.store(false, Ordering::Relaxed);
    let mut text = String::new();
    gcs_out.read_to_string(&mut text).unwrap();
    assert!(gcs.wait().unwrap().success(), "ground station exit status");
    let seen: Value = serde_json::from_str(text.trim())
        .unwrap_or_else(|e| panic!("ground station output: {e}: {text}"));
    assert!(router.terminate(), "router exit status");
    assert!(bridge.terminate(), "bridge exit status");
    stop.store(true, Ordering::Relaxed);

    let status: Vec<f64> = seen["radio_status"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["t"].as_f64().unwrap())
        .collect();
    // RADIO_STATUS at >= 0.5 Hz while the link is up (downlink never cut): no gap > 2 s
    // after the first
    assert!(status.len() >= 10, "{seen}");
    let gap = status.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    assert!(gap <= 2.0, "RADIO_STATUS gap {gap:.2} s: {seen}");
    let texts: Vec<(f64, String)> = seen["statustext"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            (
                s["t"].as_f64().unwrap(),
                s["text"].as_str().unwrap().to_owned(),
            )
        })
        .collect();
    eprintln!(
        "ground station saw: {texts:?}, {} RADIO_STATUS",
        status.len()
    );
    let uplink: Vec<&(f64, String)> = texts
        .iter()
        .filter(|(_, t)| t.starts_with("Uplink"))
        .collect();
    let alarm = uplink
        .iter()
        .find(|(_, t)| t.contains("lost") && !t.contains("restored") || t.contains("degraded"))
        .unwrap_or_else(|| panic!("no uplink alarm: {texts:?}"));
    let detect = alarm.0 - cut_at;
    assert!(
        (-0.5..=5.0).contains(&detect),
        "alarm {detect:.2} s after the cut: {texts:?}"
    );
    let restored = uplink
        .iter()
        .find(|(t, s)| *t > alarm.0 && s.contains("restored"))
        .unwrap_or_else(|| panic!("no restored: {texts:?}"));
    let restore = restored.0 - back_at;
    assert!(
        (-0.5..=5.0).contains(&restore),
        "restored {restore:.2} s after the link came back: {texts:?}"
    );
    // once per change: no uplink message repeats the one before it, none before the cut
    assert!(uplink.windows(2).all(|w| w[0].1 != w[1].1), "{texts:?}");
    assert!(uplink.iter().all(|(t, _)| *t >= cut_at - 1.0), "{texts:?}");
    // The router's status file has each announcement as an event line, in the order the
    // ground station got them (it may have announced more after the ground station left).
    let status = std::fs::read_to_string(dir.join("router.status.jsonl")).unwrap();
    let events: Vec<Value> = status
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .filter(|l| l["kind"] == "event" && l["event"] == "link_notice")
        .collect();
    let announced: Vec<&str> = events.iter().map(|e| e["text"].as_str().unwrap()).collect();
    let seen_texts: Vec<&str> = texts
        .iter()
        .map(|(_, t)| t.as_str())
        .filter(|t| t.starts_with("Uplink") || t.starts_with("Downlink"))
        .collect();
    assert!(
        announced.starts_with(&seen_texts),
        "status file {announced:?}, ground station {seen_texts:?}"
    );
    for e in &events {
        assert!(
            ["uplink", "downlink"].contains(&e["direction"].as_str().unwrap()),
            "{e}"
        );
        assert!(
            ["ok", "degraded", "lost", "silent"].contains(&e["health"].as_str().unwrap()),
            "{e}"
        );
    }
    assert!(
        events
            .iter()
            .any(|e| e["direction"] == "uplink" && e["health"] != "ok")
            && events
                .iter()
                .any(|e| e["direction"] == "uplink" && e["health"] == "ok"),
        "the cut and its end are events: {events:?}"
    );
    drop(fc);
    let _ = std::fs::remove_dir_all(&dir);
}
