//! The Mini-Circuits driver against the emulated unit over real TCP on 127.0.0.1.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use super::emulated::{EmulatedMiniCircuits, EmulatedSpec, GARBAGE, Hostile, Setter};
use super::minicircuits::{MiniCircuits, ModelSpec, Options, Transport};
use super::{Attenuator, AttenuatorError, AttenuatorRecord, DbRange, sweep};

/// Commands the driver sends on connect (`:MN?`, `:SN?`, `:FIRMWARE?`).
const CONNECT_COMMANDS: usize = 3;
/// Commands per `set_db` (`:SETATT=`, `:ATT?`).
const SET_COMMANDS: usize = 2;

fn unit(hostile: Hostile) -> (EmulatedMiniCircuits, mpsc::Receiver<f64>) {
    unit_with(EmulatedSpec {
        hostile,
        ..EmulatedSpec::default()
    })
}

fn unit_with(spec: EmulatedSpec) -> (EmulatedMiniCircuits, mpsc::Receiver<f64>) {
    let (tx, rx) = mpsc::channel();
    let setter: Setter = Box::new(move |db| {
        let _ = tx.send(db);
    });
    (
        EmulatedMiniCircuits::start(spec, setter).expect("emulator starts"),
        rx,
    )
}

fn options(emu: &EmulatedMiniCircuits, transport: Transport) -> Options {
    Options {
        port: Some(emu.addr().port()),
        transport,
        timeout: Duration::from_millis(500),
        settle: Duration::ZERO,
        ..Options::new("127.0.0.1")
    }
}

fn connect(emu: &EmulatedMiniCircuits) -> MiniCircuits {
    MiniCircuits::connect(&options(emu, Transport::Telnet)).expect("connects")
}

fn seen(rx: &mpsc::Receiver<f64>) -> Vec<f64> {
    rx.try_iter().collect()
}

#[test]
fn reads_identity_range_and_step() {
    let (emu, _rx) = unit(Hostile::Honest);
    let att = connect(&emu);
    let id = att.identity();
    assert_eq!(id.vendor, "Mini-Circuits");
    assert_eq!(id.model, "RCDAT-6000-90");
    assert_eq!(id.serial, "EMULATED-0001");
    assert_eq!(id.firmware.as_deref(), Some("EMU1"));
    assert_eq!(
        id.address,
        format!("127.0.0.1:{} (telnet)", emu.addr().port())
    );
    assert_eq!(
        att.range(),
        DbRange {
            min: 0.0,
            max: 90.0
        }
    );
    assert_eq!(att.step_db(), 0.25);
    assert_eq!(emu.commands(), vec![":MN?", ":SN?", ":FIRMWARE?"]);
}

#[test]
fn a_sweep_reads_back_and_reaches_the_setter_in_order() {
    let (emu, rx) = unit(Hostile::Honest);
    let mut att = connect(&emu);
    let points = [0.0, 10.0, 30.25, 55.5, 89.75, 90.0, 20.0];
    let mut measured = Vec::new();
    let s = sweep(&mut att, &points, |setting| measured.push(setting.db));
    assert!(s.error.is_none(), "{:?}", s.error);
    assert_eq!(measured, points);
    assert_eq!(s.done.iter().map(|d| d.db).collect::<Vec<_>>(), points);
    assert_eq!(seen(&rx), points, "the setter sees every setting, in order");
    assert_eq!(att.db().expect("reads"), 20.0);
    assert_eq!(emu.db(), 20.0);
    // Settings are confirmed in order: each settled no earlier than the one before.
    assert!(
        s.done
            .windows(2)
            .all(|w| w[0].settled_at <= w[1].settled_at)
    );
}

#[test]
fn requests_round_to_the_step_before_the_unit_sees_them() {
    let (emu, rx) = unit(Hostile::Honest);
    let mut att = connect(&emu);
    let s = att.set_db(30.1).expect("sets");
    assert_eq!((s.requested_db, s.db), (30.1, 30.0));
    let s = att.set_db(30.2).expect("sets");
    assert_eq!(s.db, 30.25);
    assert_eq!(seen(&rx), vec![30.0, 30.25]);
    let sent: Vec<_> = emu
        .commands()
        .into_iter()
        .filter(|c| c.starts_with(":SETATT"))
        .collect();
    assert_eq!(sent, vec![":SETATT=30", ":SETATT=30.25"]);
}

#[test]
fn out_of_range_is_refused_before_the_unit_is_commanded() {
    let (emu, rx) = unit(Hostile::Honest);
    let mut att = connect(&emu);
    for db in [90.2, -1.0, f64::NAN, f64::INFINITY] {
        match att.set_db(db) {
            Err(AttenuatorError::OutOfRange { range, device, .. }) => {
                assert_eq!(
                    range,
                    DbRange {
                        min: 0.0,
                        max: 90.0
                    }
                );
                assert_eq!(device.serial.as_deref(), Some("EMULATED-0001"));
            }
            other => panic!("{db}: {other:?}"),
        }
    }
    assert_eq!(
        emu.commands().len(),
        CONNECT_COMMANDS,
        "{:?}",
        emu.commands()
    );
    assert!(seen(&rx).is_empty());
    // The link is still good afterwards.
    assert_eq!(att.set_db(5.0).expect("sets").db, 5.0);
}

#[test]
fn a_refusal_carries_the_units_answer() {
    let (emu, rx) = unit(Hostile::RefuseAbove(50.0));
    let mut att = connect(&emu);
    att.set_db(40.0).expect("below the limit");
    let e = att.set_db(60.0).expect_err("refused");
    match &e {
        AttenuatorError::Refused { answer, db, .. } => {
            assert_eq!((answer.as_str(), *db), ("0", 60.0))
        }
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("\"0\""), "{e}");
    assert_eq!(
        seen(&rx),
        vec![40.0],
        "a refused value never reaches the path"
    );
}

#[test]
fn an_out_of_range_answer_is_a_refusal_with_its_code() {
    let (emu, _rx) = unit(Hostile::OutOfRangeAbove(60.0));
    let mut att = connect(&emu);
    match att.set_db(70.0) {
        Err(AttenuatorError::Refused {
            answer, meaning, ..
        }) => {
            assert_eq!(answer, "2");
            assert!(meaning.contains("range"), "{meaning}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_disconnect_mid_sweep_names_the_unit_and_keeps_the_points_done() {
    let (emu, rx) = unit(Hostile::DisconnectAfter(
        CONNECT_COMMANDS + 3 * SET_COMMANDS,
    ));
    let mut att = connect(&emu);
    let points = [10.0, 20.0, 30.0, 40.0, 50.0];
    let s = sweep(&mut att, &points, |_| {});
    assert_eq!(
        s.done.iter().map(|d| d.db).collect::<Vec<_>>(),
        [10.0, 20.0, 30.0]
    );
    let e = s.error.expect("stopped");
    assert!(matches!(e, AttenuatorError::ConnectionLost { .. }), "{e:?}");
    let text = e.to_string();
    let port = emu.addr().port().to_string();
    for part in [
        port.as_str(),
        "RCDAT-6000-90",
        "EMULATED-0001",
        ":SETATT=40",
    ] {
        assert!(text.contains(part), "{part} missing from: {text}");
    }
    assert_eq!(seen(&rx), vec![10.0, 20.0, 30.0]);
    // And the driver stays failed rather than pretending.
    assert!(matches!(
        att.set_db(10.0),
        Err(AttenuatorError::ConnectionLost { .. })
    ));
}

#[test]
fn a_stalled_unit_times_out_within_the_timeout() {
    let (emu, _rx) = unit(Hostile::StallAfter(CONNECT_COMMANDS));
    let timeout = Duration::from_millis(300);
    let mut att = MiniCircuits::connect(&Options {
        timeout,
        ..options(&emu, Transport::Telnet)
    })
    .expect("connects");
    let t0 = Instant::now();
    let e = att.set_db(10.0).expect_err("no answer");
    let took = t0.elapsed();
    match &e {
        AttenuatorError::Timeout {
            command,
            timeout: t,
            ..
        } => {
            assert_eq!(command, ":SETATT=10");
            assert_eq!(*t, timeout);
        }
        other => panic!("{other:?}"),
    }
    assert!(took >= timeout, "gave up early: {took:?}");
    assert!(
        took < timeout + Duration::from_millis(700),
        "took {took:?} against {timeout:?}"
    );
    // A late answer must not pass for the next one: the session is closed.
    assert!(matches!(
        att.db(),
        Err(AttenuatorError::ConnectionLost { .. })
    ));
}

#[test]
fn garbage_is_an_error_with_the_bytes() {
    let (emu, _rx) = unit(Hostile::GarbageAfter(CONNECT_COMMANDS + 1));
    let mut att = connect(&emu);
    // :SETATT= is answered properly, :ATT? with garbage.
    let e = att.set_db(10.0).expect_err("garbage");
    match &e {
        AttenuatorError::Garbage { command, bytes, .. } => {
            assert_eq!(command, ":ATT?");
            assert_eq!(bytes.0, GARBAGE[..GARBAGE.len() - 2]);
        }
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("\\x80\\xfe?ATT\\x01"), "{e}");
}

#[test]
fn a_readback_that_differs_is_an_error() {
    let (emu, _rx) = unit(Hostile::ReadbackOffset(0.25));
    let mut att = connect(&emu);
    match att.set_db(10.0) {
        Err(AttenuatorError::Readback {
            set_db, read_db, ..
        }) => assert_eq!((set_db, read_db), (10.0, 10.25)),
        other => panic!("{other:?}"),
    }
}

#[test]
fn an_unknown_model_needs_range_and_step_from_the_rig_file() {
    let spec = EmulatedSpec {
        model: "RCDAT-18G-63".into(),
        ..EmulatedSpec::default()
    };
    let (emu, _rx) = unit_with(spec.clone());
    match MiniCircuits::connect(&options(&emu, Transport::Telnet)) {
        Err(e @ AttenuatorError::UnknownModel { .. }) => {
            assert!(
                e.to_string().contains("RCDAT-18G-63") && e.to_string().contains("range_db"),
                "{e}"
            )
        }
        other => panic!("{:?}", other.err()),
    }
    drop(emu);
    let (emu, _rx) = unit_with(spec);
    let given = ModelSpec {
        range: DbRange {
            min: 0.0,
            max: 63.0,
        },
        step_db: 0.5,
    };
    let mut att = MiniCircuits::connect(&Options {
        range_step: Some(given),
        ..options(&emu, Transport::Telnet)
    })
    .expect("connects");
    assert_eq!(att.range().max, 63.0);
    assert_eq!(att.set_db(10.3).expect("sets").db, 10.5);
}

#[test]
fn the_settle_time_is_waited() {
    let (emu, _rx) = unit(Hostile::Honest);
    let settle = Duration::from_millis(50);
    let mut att = MiniCircuits::connect(&Options {
        settle,
        ..options(&emu, Transport::Telnet)
    })
    .expect("connects");
    let t0 = Instant::now();
    let s = att.set_db(3.0).expect("sets");
    assert!(s.settled_at.duration_since(t0) >= settle);
}

#[test]
fn an_echoing_unit_is_understood() {
    let (emu, rx) = unit_with(EmulatedSpec {
        echo: true,
        ..EmulatedSpec::default()
    });
    let mut att = connect(&emu);
    assert_eq!(att.identity().model, "RCDAT-6000-90");
    assert_eq!(att.set_db(12.5).expect("sets").db, 12.5);
    assert_eq!(seen(&rx), vec![12.5]);
}

#[test]
fn http_transport_does_the_same() {
    let (emu, rx) = unit(Hostile::Honest);
    let mut att = MiniCircuits::connect(&options(&emu, Transport::Http)).expect("connects");
    assert_eq!(att.identity().model, "RCDAT-6000-90");
    assert!(att.identity().address.ends_with("(http)"));
    let s = sweep(&mut att, &[1.0, 2.5, 3.75], |_| {});
    assert!(s.error.is_none(), "{:?}", s.error);
    assert_eq!(seen(&rx), vec![1.0, 2.5, 3.75]);
    assert!(
        emu.commands().contains(&":SETATT=2.5".to_string()),
        "{:?}",
        emu.commands()
    );
}

#[test]
fn http_refusal_and_stall() {
    let (emu, _rx) = unit(Hostile::RefuseAbove(5.0));
    let mut att = MiniCircuits::connect(&options(&emu, Transport::Http)).expect("connects");
    assert!(
        matches!(att.set_db(6.0), Err(AttenuatorError::Refused { ref answer, .. }) if answer == "0")
    );
    let (emu, _rx) = unit(Hostile::StallAfter(CONNECT_COMMANDS));
    let mut att = MiniCircuits::connect(&options(&emu, Transport::Http)).expect("connects");
    assert!(matches!(
        att.set_db(1.0),
        Err(AttenuatorError::Timeout { .. })
    ));
}

#[test]
fn nothing_listening_is_a_lost_connection_naming_the_address() {
    let port = {
        let (emu, _rx) = unit(Hostile::Honest);
        emu.addr().port()
    };
    // The emulator is gone; its port is (almost surely) closed.
    let opts = Options {
        port: Some(port),
        timeout: Duration::from_millis(300),
        ..Options::new("127.0.0.1")
    };
    match MiniCircuits::connect(&opts) {
        Err(e @ AttenuatorError::ConnectionLost { .. }) => {
            assert!(e.to_string().contains(&port.to_string()), "{e}")
        }
        other => panic!("{:?}", other.err()),
    }
}

#[test]
fn the_record_names_the_unit_and_round_trips() {
    let (emu, _rx) = unit(Hostile::Honest);
    let att = MiniCircuits::connect(&Options {
        settle: Duration::from_millis(2),
        ..options(&emu, Transport::Telnet)
    })
    .expect("connects");
    let record = att.record();
    let json = serde_json::to_value(&record).expect("serialises");
    assert_eq!(json["model"], "RCDAT-6000-90");
    assert_eq!(json["serial"], "EMULATED-0001");
    assert_eq!(json["firmware"], "EMU1");
    assert_eq!(json["range_db"]["max"], 90.0);
    assert_eq!(json["step_db"], 0.25);
    assert_eq!(json["settle_ms"], 2.0);
    let back: AttenuatorRecord = serde_json::from_value(json).expect("deserialises");
    assert_eq!(back, record);
}

#[test]
fn the_emulator_stops_on_drop() {
    let (emu, _rx) = unit(Hostile::StallAfter(0));
    let addr = emu.addr();
    // A client left hanging on a stalled unit must not keep the emulator's thread alive.
    let _client = std::net::TcpStream::connect(addr).expect("connects");
    let t0 = Instant::now();
    drop(emu);
    assert!(
        t0.elapsed() < Duration::from_secs(1),
        "drop took {:?}",
        t0.elapsed()
    );
    assert!(std::net::TcpStream::connect_timeout(&addr, Duration::from_millis(200)).is_err());
}
