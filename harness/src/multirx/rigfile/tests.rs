use super::*;
use crate::measurement::Limits;
use crate::rigfile::{DEFAULT_OUTPUT, RigFile, RigFileError};

use std::io;

const RIGS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../rigs");

/// A valid emulated rig; tests replace one line to break it.
const GOOD: &str = r#"[rig]
name = "t"

[multirx]
modes = ["parallel", "scan"]

[multirx.device]
kind = "emulated"

[multirx.device.configs]
parallel = "multirx/parallel.toml"
scan = "multirx/scan.toml"

[multirx.ports]
fc = "pty"
status = "pty"
receivers = ["pty", "pty"]

[multirx.receivers]
period_ms = 7
boot_ms = 300
"#;

fn load(text: &str) -> Result<RigFile, RigFileError> {
    RigFile::from_str_with(text, "/r/rigs/t.toml", &configs_next_to_good)
}

/// The MultiRX configs [`GOOD`] names, as if on disk next to it (with the throttle's
/// neutral that a board rig needs).
fn configs_next_to_good(path: &Path) -> io::Result<String> {
    const THROTTLE: &str = "[neutral]\nthrottle_channel = 3\nthrottle = 992\n";
    match path.to_str() {
        Some("/r/rigs/multirx/parallel.toml") => {
            Ok(format!("mode = \"parallel\"\nreceivers = 2\n{THROTTLE}"))
        }
        Some("/r/rigs/multirx/scan.toml") => {
            Ok(format!("mode = \"scan\"\nreceivers = 2\n{THROTTLE}"))
        }
        _ => Err(io::ErrorKind::NotFound.into()),
    }
}

fn replace(from: &str, to: &str) -> String {
    assert!(GOOD.contains(from), "{from:?} not in GOOD");
    GOOD.replacen(from, to, 1)
}

/// Asserts an `Invalid` error at `line` about `field`, with `needle` in
/// its message, and that Display names file, line and field.
#[track_caller]
fn assert_invalid(text: &str, line: usize, field: &str, needle: &str) {
    let err = load(text).expect_err("should be rejected");
    let shown = err.to_string();
    match &err {
        RigFileError::Invalid {
            line: l,
            field: f,
            message,
            ..
        } => {
            assert_eq!((*l, f.as_str()), (line, field), "{shown}");
            assert!(message.contains(needle), "{shown}");
        }
        other => panic!("expected Invalid, got {other:?}"),
    }
    assert!(
        shown.starts_with(&format!("/r/rigs/t.toml:{line}:")),
        "{shown}"
    );
    assert!(shown.contains(&format!(": {field}: ")), "{shown}");
}

#[track_caller]
fn assert_syntax(text: &str, line: usize, field: Option<&str>, needle: &str) {
    let err = load(text).expect_err("should be rejected");
    let shown = err.to_string();
    match &err {
        RigFileError::Syntax {
            line: l,
            field: f,
            message,
            ..
        } => {
            assert_eq!((*l, f.as_deref()), (line, field), "{shown}");
            assert!(message.contains(needle), "{shown}");
        }
        other => panic!("expected Syntax, got {other:?}"),
    }
    assert!(
        shown.starts_with(&format!("/r/rigs/t.toml:{line}:")),
        "{shown}"
    );
}

#[test]
fn good_file_loads_with_defaults_and_absolute_paths() {
    let rig = load(GOOD).unwrap();
    assert_eq!(rig.path, Path::new("/r/rigs/t.toml"));
    assert_eq!(rig.rig.name, "t");
    assert_eq!(rig.rig.output, None);
    assert_eq!(rig.output_dir(), Path::new(DEFAULT_OUTPUT));
    assert_eq!(rig.fixtures.python, Path::new("python3"));
    assert_eq!(rig.fixtures.dir, Path::new("/r/fixtures"));
    let m = rig.devices.multirx.as_ref().unwrap();
    assert_eq!(m.modes, [Mode::Parallel, Mode::Scan]);
    assert_eq!(m.device.kind(), DeviceKind::Emulated);
    assert_eq!(m.device.setup, DeviceSetup::Emulated { program: None });
    let scan = m.config(Mode::Scan).unwrap();
    assert_eq!(scan.path, Path::new("/r/rigs/multirx/scan.toml"));
    assert_eq!(
        scan.config,
        multirx_core::Config {
            throttle_channel: Some(2),
            ..multirx_core::Config::new(multirx_core::Mode::Scan, 2)
        }
    );
    assert_eq!(m.ports.receivers, [PortSpec::Pty, PortSpec::Pty]);
    assert_eq!(m.ports.ifs, None);
    assert_eq!(m.receivers, ReceiversSection::default());
    assert!(rig.limits.is_empty());
}

#[test]
fn relative_path_resolves_against_rig_folder() {
    let text = replace("name = \"t\"", "name = \"t\"\noutput = \"./out/../report\"")
        .replace("status = \"pty\"", "status = \"dev/ttyS9\"")
        .replace(
            "kind = \"emulated\"",
            "kind = \"emulated\"\nprogram = \"bin/emu\"",
        );
    let rig = load(&text).unwrap();
    assert_eq!(rig.rig.output.as_deref(), Some(Path::new("/r/rigs/report")));
    let m = rig.devices.multirx.unwrap();
    assert_eq!(m.ports.status, PortSpec::Path("/r/rigs/dev/ttyS9".into()));
    assert_eq!(
        m.device.setup,
        DeviceSetup::Emulated {
            program: Some("/r/rigs/bin/emu".into())
        }
    );
}

#[test]
fn checked_in_emulated_rig_loads() {
    let rig = RigFile::load(format!("{RIGS}/emulated.toml")).unwrap();
    assert_eq!(rig.rig.name, "emulated");
    assert!(rig.path.is_absolute());
    let rigs = rig.path.parent().unwrap();
    assert_eq!(rig.fixtures.dir, rigs.parent().unwrap().join("fixtures"));
    assert!(
        rig.fixtures.dir.join("sbus_receiver.py").is_file(),
        "{}",
        rig.fixtures.dir.display()
    );
    let m = rig.devices.multirx.unwrap();
    assert_eq!(m.modes, Mode::ALL);
    assert_eq!(m.device.kind(), DeviceKind::Emulated);
    assert_eq!(m.ports.receivers, vec![PortSpec::Pty; 6]);
    assert_eq!(m.ports.ifs, Some(PortSpec::Pty));
    assert_eq!(m.ports.fc, PortSpec::Pty);
    assert_eq!(m.receivers.period_ms, 7);
    assert_eq!(m.receivers.boot_ms, 300);
    let parallel = m.config(Mode::Parallel).unwrap();
    assert_eq!(parallel.path, rigs.join("multirx/parallel.toml"));
    assert_eq!(parallel.config.mode, multirx_core::Mode::Parallel);
    assert_eq!(
        m.config(Mode::Scan).unwrap().config.mode,
        multirx_core::Mode::Scan
    );
    assert!(rig.limits.is_empty());
}

#[test]
fn checked_in_bench_example_loads() {
    let rig = RigFile::load(format!("{RIGS}/bench.example.toml")).unwrap();
    let m = rig.devices.multirx.unwrap();
    assert_eq!(m.device.kind(), DeviceKind::Board);
    assert_eq!(
        m.device.setup,
        DeviceSetup::Board(BoardSetup {
            probe: ProbeSelector::Auto,
            chip: "ATSAMD21G18A".into(),
            flash: true,
            firmware: std::fs::canonicalize(format!("{RIGS}/../firmware/multirx/samd21")).unwrap(),
        })
    );
    assert_eq!(m.ports.receivers.len(), 2);
    assert!(
        matches!(&m.ports.fc, PortSpec::Path(p) if p.starts_with("/dev/serial/by-id")),
        "{:?}",
        m.ports.fc
    );
}

#[test]
fn too_many_receivers_names_line_and_field() {
    let text = replace(
        "receivers = [\"pty\", \"pty\"]",
        "receivers = [\"pty\", \"pty\", \"pty\", \"pty\", \"pty\", \"pty\", \"pty\"]",
    );
    assert_invalid(
        &text,
        17,
        "multirx.ports.receivers",
        "7 receivers given, at most 6",
    );
    let shown = load(&text).unwrap_err().to_string();
    assert_eq!(
        shown,
        "/r/rigs/t.toml:17:1: multirx.ports.receivers: 7 receivers given, at most 6"
    );
}

#[test]
fn no_receivers_rejected() {
    let text = replace("receivers = [\"pty\", \"pty\"]", "receivers = []");
    assert_invalid(&text, 17, "multirx.ports.receivers", "at least 1");
}

#[test]
fn mode_without_config_points_at_configs_table() {
    let text = replace("scan = \"multirx/scan.toml\"\n", "");
    assert_invalid(
        &text,
        10,
        "multirx.device.configs.scan",
        "has no MultiRX config file",
    );
    // No configs table at all: the device table is the nearest.
    let text = replace(
        "[multirx.device.configs]\nparallel = \"multirx/parallel.toml\"\nscan = \"multirx/scan.toml\"\n",
        "",
    );
    assert_invalid(&text, 7, "multirx.device.configs.parallel", "\"parallel\"");
}

#[test]
fn a_scan_config_under_the_parallel_key_is_named_by_file_and_key() {
    let text = replace(
        "parallel = \"multirx/parallel.toml\"",
        "parallel = \"multirx/scan.toml\"",
    );
    assert_invalid(
        &text,
        11,
        "multirx.device.configs.parallel",
        "/r/rigs/multirx/scan.toml says mode = \"scan\"; the parallel suite needs a config with mode = \"parallel\"",
    );
}

#[test]
fn a_config_too_large_for_the_board_names_its_file_and_key() {
    let six = "receivers = [\"pty\", \"pty\", \"pty\", \"pty\", \"pty\", \"pty\"]";
    let text = replace("receivers = [\"pty\", \"pty\"]", six);
    let six_with_ifs = |_: &Path| -> io::Result<String> {
        Ok("mode = \"parallel\"\nreceivers = 6\n\n[ifs]\nchannels = [5]\n".into())
    };
    let text = text
        .replace("modes = [\"parallel\", \"scan\"]", "modes = [\"parallel\"]")
        .replace("scan = \"multirx/scan.toml\"\n", "");
    // The emulated device has no SERCOMs to run out of.
    RigFile::from_str_with(&text, "/r/rigs/t.toml", &six_with_ifs).unwrap();
    let board = text.replace("kind = \"emulated\"", "kind = \"board\"");
    let err = RigFile::from_str_with(&board, "/r/rigs/t.toml", &six_with_ifs).unwrap_err();
    assert!(
        matches!(&err, RigFileError::Config { field, .. } if field == "multirx.device.configs.parallel"),
        "{err:?}"
    );
    assert_eq!(
        err.to_string(),
        "/r/rigs/multirx/parallel.toml:2:1: receivers: 6 receivers and an [ifs] input need 7 UART inputs; \
         the board has 6, so at most 5 receivers with [ifs] (multirx.device.configs.parallel in /r/rigs/t.toml)"
    );
}

#[test]
fn a_bench_config_must_name_its_throttle_neutral_and_an_emulated_one_need_not() {
    let board = replace("kind = \"emulated\"", "kind = \"board\"");
    let default_neutral = |p: &Path| -> io::Result<String> {
        configs_next_to_good(p).map(|t| {
            t.replace(
                "throttle_channel = 3\nthrottle = 992\n",
                "values = [992, 992, 992, 992, 1811, 992, 992, 992, 992, 172, 992, 992, 992, 992, 992, 992]\n",
            )
        })
    };
    // The emulated rig keeps flying the default neutral.
    RigFile::from_str_with(GOOD, "/r/rigs/t.toml", &default_neutral).unwrap();
    let err = RigFile::from_str_with(&board, "/r/rigs/t.toml", &default_neutral).unwrap_err();
    assert!(
        matches!(&err, RigFileError::Config { field, .. } if field == "multirx.device.configs.parallel"),
        "{err:?}"
    );
    let shown = err.to_string();
    assert!(
        shown.starts_with("/r/rigs/multirx/parallel.toml:3:2: neutral.throttle_channel: "),
        "{shown}"
    );
    assert!(
        shown.ends_with("(multirx.device.configs.parallel in /r/rigs/t.toml)"),
        "{shown}"
    );
    // Named, it loads.
    RigFile::from_str_with(&board, "/r/rigs/t.toml", &configs_next_to_good).unwrap();
}

#[test]
fn config_errors_are_located_in_the_config_or_at_its_key() {
    // Receivers that do not match the ports.
    let three = |p: &Path| -> io::Result<String> {
        configs_next_to_good(p).map(|t| t.replace("receivers = 2", "receivers = 3"))
    };
    let err = RigFile::from_str_with(GOOD, "/r/rigs/t.toml", &three).unwrap_err();
    assert_eq!(
        err.to_string(),
        "/r/rigs/t.toml:11:1: multirx.device.configs.parallel: /r/rigs/multirx/parallel.toml \
         configures 3 receivers but multirx.ports.receivers lists 2 ports"
    );
    // A value MultiRX cannot fly with: the config's own line and key.
    let bad = |p: &Path| -> io::Result<String> {
        configs_next_to_good(p).map(|t| t + "\n[link]\nsilence_timeout_ms = 5\n")
    };
    let err = RigFile::from_str_with(GOOD, "/r/rigs/t.toml", &bad).unwrap_err();
    assert!(
        err.to_string().starts_with(
            "/r/rigs/multirx/parallel.toml:8:1: link.silence_timeout_ms: 5 is outside 20..=1000"
        ),
        "{err}"
    );
    // Missing: the rig file's key that names it.
    let text = replace(
        "scan = \"multirx/scan.toml\"",
        "scan = \"multirx/sacn.toml\"",
    );
    let err = load(&text).unwrap_err();
    assert!(
        matches!(err, RigFileError::ConfigRead { line: 12, .. }),
        "{err:?}"
    );
    assert!(
        err.to_string().starts_with(
            "/r/rigs/t.toml:12:1: multirx.device.configs.scan: cannot read /r/rigs/multirx/sacn.toml: "
        ),
        "{err}"
    );
}

#[test]
fn listing_only_one_mode_needs_only_its_config() {
    let text = replace("modes = [\"parallel\", \"scan\"]", "modes = [\"scan\"]")
        .replace("parallel = \"multirx/parallel.toml\"\n", "");
    let m = load(&text).unwrap().devices.multirx.unwrap();
    assert_eq!(m.modes, [Mode::Scan]);
}

#[test]
fn bad_modes_rejected() {
    assert_invalid(
        &replace("modes = [\"parallel\", \"scan\"]", "modes = []"),
        5,
        "multirx.modes",
        "empty",
    );
    assert_invalid(
        &replace(
            "modes = [\"parallel\", \"scan\"]",
            "modes = [\"scan\", \"scan\"]",
        ),
        5,
        "multirx.modes",
        "listed twice",
    );
    assert_syntax(
        &replace("modes = [\"parallel\", \"scan\"]", "modes = [\"paralel\"]"),
        5,
        Some("multirx.modes"),
        "unknown variant `paralel`",
    );
}

#[test]
fn period_and_boot_ranges() {
    assert_invalid(
        &replace("period_ms = 7", "period_ms = 10"),
        20,
        "multirx.receivers.period_ms",
        "7 ms (high speed) or 14 ms",
    );
    assert!(load(&replace("period_ms = 7", "period_ms = 14")).is_ok());
    assert_invalid(
        &replace("boot_ms = 300", "boot_ms = 5001"),
        21,
        "multirx.receivers.boot_ms",
        "out of range 0..=5000",
    );
    assert!(load(&replace("boot_ms = 300", "boot_ms = 5000")).is_ok());
    assert!(load(&replace("boot_ms = 300", "boot_ms = 0")).is_ok());
    assert_syntax(
        &replace("boot_ms = 300", "boot_ms = -1"),
        21,
        Some("multirx.receivers.boot_ms"),
        "expected u32",
    );
}

#[test]
fn unknown_field_typo_names_line_and_key() {
    let text = replace(
        "receivers = [\"pty\", \"pty\"]",
        "recievers = [\"pty\", \"pty\"]",
    );
    assert_syntax(
        &text,
        17,
        Some("multirx.ports.recievers"),
        "unknown field `recievers`",
    );
    let text = replace(
        "[rig]\nname = \"t\"",
        "[rig]\nname = \"t\"\ncolour = \"red\"",
    );
    assert_syntax(&text, 3, Some("rig.colour"), "unknown field `colour`");
    let text = format!("{GOOD}\n[radio]\nmodel = \"sik\"\n");
    assert_syntax(&text, 23, Some("radio"), "unknown field `radio`");
}

#[test]
fn missing_required_key_names_its_table() {
    let text = replace("fc = \"pty\"\n", "");
    assert_syntax(&text, 14, Some("multirx.ports"), "missing field `fc`");
}

#[test]
fn toml_syntax_error_has_line() {
    let text = replace("[multirx.receivers]", "[multirx.receivers");
    assert_syntax(&text, 19, None, "");
    let err = load("[rig]\nname = \"t\"\nname = \"u\"\n").unwrap_err();
    assert!(
        matches!(err, RigFileError::Syntax { line: 3, .. }),
        "duplicate key: {err}"
    );
}

#[test]
fn ports_must_be_pty_or_a_path() {
    assert_syntax(
        &replace("fc = \"pty\"", "fc = \"\""),
        15,
        Some("multirx.ports.fc"),
        "empty port",
    );
    assert_syntax(
        &replace("fc = \"pty\"", "fc = \"PTY\""),
        15,
        Some("multirx.ports.fc"),
        "neither \"pty\" nor a device path",
    );
    assert_syntax(
        &replace("fc = \"pty\"", "fc = 3"),
        15,
        Some("multirx.ports.fc"),
        "expected a string",
    );
}

#[test]
fn one_device_path_for_two_lines_rejected() {
    let text = replace("fc = \"pty\"", "fc = \"/dev/ttyUSB0\"").replace(
        "receivers = [\"pty\", \"pty\"]",
        "receivers = [\"pty\", \"/dev/ttyUSB0\"]",
    );
    assert_invalid(
        &text,
        17,
        "multirx.ports.receivers[1]",
        "also used for multirx.ports.fc",
    );
}

#[test]
fn board_keys_on_emulated_device_rejected() {
    let text = replace("kind = \"emulated\"", "kind = \"emulated\"\nflash = true");
    assert_invalid(
        &text,
        9,
        "multirx.device.flash",
        "only for kind = \"board\"",
    );
    let text = replace(
        "kind = \"emulated\"",
        "kind = \"board\"\nprogram = \"multirx-emu\"",
    );
    assert_invalid(
        &text,
        9,
        "multirx.device.program",
        "only for kind = \"emulated\"",
    );
    assert_syntax(
        &replace("kind = \"emulated\"", "kind = \"samd21\""),
        8,
        Some("multirx.device.kind"),
        "unknown variant `samd21`",
    );
}

#[test]
fn board_probe_and_defaults() {
    let board = |extra: &str| {
        load(&replace(
            "kind = \"emulated\"",
            &format!("kind = \"board\"\n{extra}"),
        ))
    };
    let m = board("").unwrap().devices.multirx.unwrap();
    assert_eq!(
        m.device.setup,
        DeviceSetup::Board(BoardSetup {
            probe: ProbeSelector::Auto,
            chip: DEFAULT_CHIP.into(),
            flash: false,
            firmware: PathBuf::from("/r/firmware/multirx/samd21"),
        })
    );
    let m = board("probe = \"2E8A:000c:E66118\"")
        .unwrap()
        .devices
        .multirx
        .unwrap();
    let DeviceSetup::Board(b) = &m.device.setup else {
        panic!()
    };
    assert_eq!(
        b.probe,
        ProbeSelector::Usb {
            vid: 0x2e8a,
            pid: 0x000c,
            serial: Some("E66118".into())
        }
    );
    assert_eq!(b.probe.to_string(), "2e8a:000c:E66118");
    let err = board("probe = \"stlink\"").unwrap_err();
    assert!(
        matches!(&err, RigFileError::Invalid { line: 9, field, .. } if field == "multirx.device.probe"),
        "{err}"
    );
}

#[test]
fn limits_are_checked_and_located() {
    let text = format!(
        "{GOOD}\n[limits]\n\"multirx.parallel.handover_ms\" = {{ max = 50.0 }}\n\
         \"multirx.scan.handover_ms\" = {{ max = 4500.0, marginal_max = 4000.0 }}\n"
    );
    let rig = load(&text).unwrap();
    assert_eq!(
        rig.limits_for("multirx.scan.handover_ms", Limits::NONE),
        Limits {
            max: Some(4500.0),
            marginal_max: Some(4000.0),
            ..Limits::NONE
        }
    );
    let builtin = Limits {
        max: Some(1.0),
        ..Limits::NONE
    };
    assert_eq!(rig.limits_for("other", builtin), builtin);
    assert!(
        rig.check_limit_names(["multirx.parallel.handover_ms", "multirx.scan.handover_ms"])
            .is_ok()
    );
    let err = rig
        .check_limit_names(["multirx.parallel.handover_ms"])
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "/r/rigs/t.toml:25:1: limits.\"multirx.scan.handover_ms\": \
         no measurement is named \"multirx.scan.handover_ms\""
    );

    let bad = format!("{GOOD}\n[limits]\n\"a.b\" = {{ min = 50.0, max = 10.0 }}\n");
    assert_invalid(&bad, 24, "limits.\"a.b\"", "need min <= max");
    let empty = format!("{GOOD}\n[limits]\n\"a.b\" = {{}}\n");
    assert_invalid(&empty, 24, "limits.\"a.b\"", "no limit given");
    let typo = format!("{GOOD}\n[limits]\n\"a.b\" = {{ maximum = 1.0 }}\n");
    assert_syntax(
        &typo,
        24,
        Some("limits.\"a.b\".maximum"),
        "unknown field `maximum`",
    );
}

#[test]
fn empty_rig_name_and_missing_rig_table() {
    assert_invalid(
        &replace("name = \"t\"", "name = \" \""),
        2,
        "rig.name",
        "empty",
    );
    let err = load("[fixtures]\npython = \"python3\"\n").unwrap_err();
    assert!(
        matches!(&err, RigFileError::Syntax { line: 1, message, .. } if message.contains("missing field `rig`")),
        "{err}"
    );
}

#[test]
fn no_multirx_section_is_allowed() {
    let rig = load("[rig]\nname = \"mavlora-only\"\n").unwrap();
    assert!(rig.devices.multirx.is_none());
}

#[test]
fn read_error_names_path() {
    let err = RigFile::load("/nonexistent/rig.toml").unwrap_err();
    assert!(matches!(err, RigFileError::Read { .. }));
    assert_eq!(
        err.to_string(),
        "/nonexistent/rig.toml: cannot read rig file"
    );
    assert!(std::error::Error::source(&err).is_some());
}

#[test]
fn column_counts_characters() {
    let text = replace("[rig]\nname = \"t\"", "[rig]\nname = \"t\"\n\"é\" = 1");
    let err = load(&text).unwrap_err();
    assert!(
        matches!(
            err,
            RigFileError::Syntax {
                line: 3,
                column: 1,
                ..
            }
        ),
        "{err}"
    );
    let text = replace("fc = \"pty\"", "fc = \"pty\"\n  recievers = []");
    let err = load(&text).unwrap_err();
    assert!(
        matches!(
            err,
            RigFileError::Syntax {
                line: 16,
                column: 3,
                ..
            }
        ),
        "{err}"
    );
}
