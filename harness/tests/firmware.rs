//! The rig's built → flashed strategy on this machine: the firmware builds
//! with a rig's MultiRX config compiled in, and flashing without a probe says so.

use std::path::Path;

use harness::multirx::firmware;
use harness::multirx::rigfile::ProbeSelector;

fn repo() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

#[test]
fn firmware_builds_with_a_rig_config_and_reports_its_size() {
    let image = firmware::build(
        &repo().join("firmware/multirx/samd21"),
        &repo().join("rigs/multirx/bench-parallel.toml"),
    )
    .unwrap();
    assert!((4_096..64 * 1024).contains(&image.flash_bytes), "{image:?}");
    assert!(image.ram_bytes < 32 * 1024, "{image:?}");
    assert_eq!(image.sha256.len(), 64);

    // No debug probe on a CI machine: the error must say so, not hang or panic.
    let driver = harness::multirx::driver::probe::ProbeDriver {
        selector: ProbeSelector::Auto,
        chip: "ATSAMD21G18A".into(),
    };
    if let Err(e) = driver.flash(&image.elf) {
        let text = format!("{e:#}");
        assert!(text.contains("probe"), "{text}");
    }
}

#[test]
fn firmware_build_refuses_a_config_the_board_cannot_wire() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("six-plus-ifs.toml");
    std::fs::write(
        &config,
        "mode = \"parallel\"\nreceivers = 6\n[ifs]\nchannels = [5]\n",
    )
    .unwrap();
    let err = firmware::build(&repo().join("firmware/multirx/samd21"), &config).unwrap_err();
    assert!(format!("{err:#}").contains("failed"), "{err:#}");
}
