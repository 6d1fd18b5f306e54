use super::*;

#[test]
fn values_render_with_at_most_three_decimals() {
    assert_eq!(format_value(0.6998300004852354), "0.7");
    assert_eq!(format_value(63.4919), "63.492");
    assert_eq!(format_value(5.0), "5");
    assert_eq!(format_value(-0.0001), "0");
}

#[test]
fn new_measurement_is_unset() {
    let m = Spec::new("a", "ms").at_most(50.0).unset();
    assert_eq!(m.outcome, Outcome::Unset);
    assert_eq!(m.value, None);
    assert!(!m.outcome.is_passing());
}

#[test]
fn at_most_passes_at_the_limit_and_fails_above() {
    let mut m = Spec::new("a", "ms").at_most(50.0).unset();
    assert_eq!(m.record(50.0), Outcome::Pass);
    assert_eq!(m.record(50.001), Outcome::Fail);
    assert_eq!(m.value, Some(50.001), "failing value kept");
    assert_eq!(m.limits.max, Some(50.0), "limit kept");
}

#[test]
fn at_least_fails_below() {
    let mut m = Spec::new("rate", "Hz").at_least(3.0).unset();
    assert_eq!(m.record(2.9), Outcome::Fail);
    assert_eq!(m.record(3.0), Outcome::Pass);
}

#[test]
fn between_and_equal() {
    let mut m = Spec::new("a", "").between(10.0, 20.0).unset();
    assert_eq!(m.record(9.0), Outcome::Fail);
    assert_eq!(m.record(15.0), Outcome::Pass);
    assert_eq!(m.record(21.0), Outcome::Fail);
    let mut e = Spec::new("lost", "").equal_to(0.0).unset();
    assert_eq!(e.record(0.0), Outcome::Pass);
    assert_eq!(e.record(1.0), Outcome::Fail);
}

#[test]
fn marginal_band_is_inclusive_and_passing() {
    let mut m = Spec::new("h", "ms")
        .at_most(4500.0)
        .marginal_above(4000.0)
        .unset();
    assert_eq!(m.record(3999.0), Outcome::Pass);
    assert_eq!(m.record(4000.0), Outcome::Marginal);
    assert!(Outcome::Marginal.is_passing());
    assert_eq!(m.record(4500.0), Outcome::Marginal);
    assert_eq!(m.record(4500.5), Outcome::Fail);
    let mut lo = Spec::new("rate", "Hz")
        .at_least(3.0)
        .marginal_below(3.5)
        .unset();
    assert_eq!(lo.record(3.2), Outcome::Marginal);
    assert_eq!(lo.record(4.0), Outcome::Pass);
}

#[test]
fn nan_fails_even_without_limits() {
    let mut m = Spec::new("a", "ms").unset();
    assert_eq!(m.record(f64::NAN), Outcome::Fail);
    assert!(m.note.as_deref().unwrap().contains("NaN"));
    let mut n = Spec::new("b", "ms").unset();
    assert_eq!(n.record(1e9), Outcome::Pass, "no limits: any number");
}

#[test]
fn infinity_is_judged_against_limits() {
    let mut m = Spec::new("a", "ms").at_most(50.0).unset();
    assert_eq!(m.record(f64::INFINITY), Outcome::Fail);
}

#[test]
fn skip_keeps_reason() {
    let mut m = Spec::new("a", "ms").at_most(50.0).unset();
    m.record(10.0);
    m.skip("scan mode not in this rig");
    assert_eq!(m.outcome, Outcome::Skipped);
    assert_eq!(m.value, None);
    assert_eq!(m.note.as_deref(), Some("scan mode not in this rig"));
    assert!(m.outcome.is_passing());
}

#[test]
fn limits_render() {
    let r = |s: Spec| s.limits.render(&s.unit);
    assert_eq!(r(Spec::new("a", "ms").at_most(50.0)), "x <= 50 ms");
    assert_eq!(
        r(Spec::new("a", "ms").between(10.0, 50.0)),
        "10 <= x <= 50 ms"
    );
    assert_eq!(r(Spec::new("a", "").equal_to(0.0)), "x == 0");
    assert_eq!(r(Spec::new("a", "Hz").at_least(3.0)), "x >= 3 Hz");
    assert_eq!(r(Spec::new("a", "B/s")), "none");
    assert_eq!(
        r(Spec::new("a", "ms").at_most(4500.0).marginal_above(4000.0)),
        "x <= 4500 ms (marginal: x >= 4000 ms)"
    );
    assert_eq!(
        r(Spec::new("a", "ms")
            .between(1.0, 9.0)
            .marginal_below(2.0)
            .marginal_above(8.5)),
        "1 <= x <= 9 ms (marginal: x <= 2 or x >= 8.5 ms)"
    );
    assert_eq!(
        Limits {
            max: Some(0.5),
            ..Limits::NONE
        }
        .to_string(),
        "x <= 0.5"
    );
}

#[test]
fn render_value() {
    let mut m = Spec::new("a", "ms").unset();
    assert_eq!(m.render_value(), "unset");
    m.record(12.5);
    assert_eq!(m.render_value(), "12.5 ms");
    m.skip("why");
    assert_eq!(m.render_value(), "skipped");
}

#[test]
fn validate_rejects_disordered_and_non_finite_limits() {
    let ok = Limits {
        min: Some(1.0),
        max: Some(9.0),
        marginal_min: Some(2.0),
        marginal_max: Some(8.0),
    };
    assert_eq!(ok.validate(), Ok(()));
    let bad = Limits {
        min: Some(50.0),
        max: Some(10.0),
        ..Limits::NONE
    };
    assert!(bad.validate().unwrap_err().contains("min <= max"));
    let band_outside = Limits {
        max: Some(4000.0),
        marginal_max: Some(4500.0),
        ..Limits::NONE
    };
    assert!(
        band_outside
            .validate()
            .unwrap_err()
            .contains("marginal_max < max")
    );
    let nan = Limits {
        max: Some(f64::NAN),
        ..Limits::NONE
    };
    assert!(nan.validate().is_err());
}

#[test]
fn serde_outcome_lowercase_and_round_trip() {
    let mut m = Spec::new("a", "ms").describe("d").at_most(50.0).unset();
    m.record(60.0);
    let json = serde_json::to_string(&m).unwrap();
    assert!(json.contains(r#""outcome":"fail""#), "{json}");
    assert!(json.contains(r#""value":60.0"#), "{json}");
    let back: Measurement = serde_json::from_str(&json).unwrap();
    assert_eq!(back, m);
}

fn multirx(mode: &str) -> Spec {
    Spec::new("max_output_gap_ms", "ms")
        .dim(Dimension::Device, "multirx")
        .dim(Dimension::Mode, mode)
}

#[test]
fn declared_handle_records_and_annotates_its_measurement() {
    let mut phase = Declarations::new();
    let gap = phase.declare(multirx("parallel").at_most(10.5));
    let losses = phase.declare(Spec::new("rc_losses", "").equal_to(0.0));
    assert_eq!(phase.get(gap).outcome, Outcome::Unset);
    assert_eq!(phase.record(gap, 11.0).outcome, Outcome::Fail);
    phase.annotate(gap, "measured at the adapter");
    assert_eq!(phase.record(losses, 0.0).outcome, Outcome::Pass);
    let ms = phase.into_measurements();
    assert_eq!(ms.len(), 2);
    assert_eq!(ms[0].name, "multirx.parallel.max_output_gap_ms");
    assert_eq!(ms[0].value, Some(11.0));
    assert_eq!(ms[0].note.as_deref(), Some("measured at the adapter"));
    assert_eq!(ms[1].name, "rc_losses");
}

#[test]
#[should_panic(expected = "another phase")]
fn a_handle_records_only_in_the_phase_that_declared_it() {
    let mut a = Declarations::new();
    let mut b = Declarations::new();
    let h = a.declare(multirx("parallel"));
    b.declare(multirx("parallel"));
    b.record(h, 1.0);
}

#[test]
#[should_panic(expected = "declared twice")]
fn one_name_is_declared_once_per_phase() {
    let mut phase = Declarations::new();
    phase.declare(multirx("scan"));
    phase.declare(multirx("scan").at_most(1.0));
}

#[test]
#[should_panic(expected = "one segment")]
fn a_base_name_has_no_dots() {
    Spec::new("naive.mission_upload_s", "s");
}

#[test]
fn flat_names_are_made_from_the_dimensions() {
    let name = |spec: Spec| spec.name();
    assert_eq!(
        name(multirx("scan").dim(Dimension::Scenario, "b_handover")),
        "multirx.scan.b_handover.max_output_gap_ms"
    );
    // the order is the dimensions', not the order they were given in
    assert_eq!(
        name(
            Spec::new("handover_ms", "ms")
                .dim(Dimension::Mode, "parallel")
                .dim(Dimension::Device, "multirx")
        ),
        "multirx.parallel.handover_ms"
    );
    assert_eq!(
        name(
            Spec::new("flash_bytes", "B")
                .dim(Dimension::Device, "multirx")
                .dim(Dimension::Mode, "scan")
                .dim(Dimension::Artifact, "firmware")
        ),
        "firmware.scan.flash_bytes"
    );
    let mavlora = |base: &str| Spec::new(base, "").dim(Dimension::Device, "mavlora");
    assert_eq!(
        name(
            mavlora("bytes_per_s")
                .dim(Dimension::Transport, "pty")
                .dim(Dimension::Variant, "compact")
        ),
        "mavlora.pty.compact.bytes_per_s"
    );
    assert_eq!(
        name(
            mavlora("bytes_per_s")
                .dim(Dimension::Transport, SIMULATED)
                .dim(Dimension::Variant, "limit_filter")
        ),
        "mavlora.limit_filter.bytes_per_s"
    );
    let mission = |variant: &str| {
        name(
            mavlora("mission_upload_s")
                .dim(Dimension::Transport, SIMULATED)
                .dim(Dimension::Radio, "lora_sf7")
                .dim(Dimension::Variant, variant),
        )
    };
    assert_eq!(mission(RELAY), "mavlora.lora_sf7.mission_upload_s");
    assert_eq!(mission("naive"), "mavlora.lora_sf7.naive.mission_upload_s");
    assert_eq!(
        name(mavlora("detect_s").dim(Dimension::Scenario, "blind_drone")),
        "mavlora.blind_drone.detect_s"
    );
}

#[test]
fn base_name_is_the_flat_name_without_the_dimensions() {
    let mut phase = Declarations::new();
    let h = phase.declare(
        Spec::new("mission_upload_s", "s")
            .dim(Dimension::Device, "mavlora")
            .dim(Dimension::Transport, SIMULATED)
            .dim(Dimension::Radio, "sik_64k")
            .dim(Dimension::Variant, "naive"),
    );
    assert_eq!(phase.get(h).base(), Some("mission_upload_s"));
    let old = Measurement {
        dimensions: Dimensions::default(),
        ..phase.get(h).clone()
    };
    assert_eq!(old.base(), None, "no dimensions, no base name");
}

#[test]
fn selector_matches_base_and_dimensions() {
    let mut phase = Declarations::new();
    let session =
        |mode: &str, scenario: &str| multirx(mode).dim(Dimension::Scenario, scenario.to_owned());
    phase.declare(session("parallel", "a_idle_takeover"));
    phase.declare(session("parallel", "b_handover"));
    phase.declare(session("scan", "b_handover"));
    phase.declare(multirx("parallel"));
    phase.declare(Spec::new("rc_losses", "").dim(Dimension::Device, "multirx"));
    let names = |s: &Selector| -> Vec<String> {
        phase
            .measurements()
            .iter()
            .filter(|m| s.matches(m))
            .map(|m| m.name.clone())
            .collect()
    };
    assert_eq!(names(&Selector::any()).len(), 5);
    assert_eq!(names(&Selector::base("max_output_gap_ms")).len(), 4);
    assert_eq!(
        names(&Selector::like(&multirx("parallel")).has(Dimension::Scenario)),
        [
            "multirx.parallel.a_idle_takeover.max_output_gap_ms",
            "multirx.parallel.b_handover.max_output_gap_ms"
        ]
    );
    assert_eq!(
        names(&Selector::any().dim(Dimension::Scenario, "b_handover")),
        [
            "multirx.parallel.b_handover.max_output_gap_ms",
            "multirx.scan.b_handover.max_output_gap_ms"
        ]
    );
    assert_eq!(
        names(&Selector::base("rc_losses").dim(Dimension::Device, "multirx")),
        ["multirx.rc_losses"]
    );
    assert!(names(&Selector::base("rc_losses").dim(Dimension::Mode, "scan")).is_empty());
}

#[test]
fn dimensions_are_saved_as_an_object_and_read_back() {
    let mut m = multirx("scan").dim(Dimension::Scenario, "c_loiter").unset();
    m.record(7.0);
    let json = serde_json::to_string(&m).unwrap();
    assert!(
        json.contains(r#""dimensions":{"device":"multirx","mode":"scan","scenario":"c_loiter"}"#),
        "{json}"
    );
    let back: Measurement = serde_json::from_str(&json).unwrap();
    assert_eq!(back, m);
    assert_eq!(back.base(), Some("max_output_gap_ms"));
}

#[test]
fn a_measurement_saved_without_dimensions_loads() {
    let old = r#"{"name": "multirx.scan.handover_ms", "unit": "ms", "description": "",
        "limits": {"max": 4500.0}, "value": 12.0, "outcome": "pass"}"#;
    let m: Measurement = serde_json::from_str(old).unwrap();
    assert!(m.dimensions.is_empty());
    assert_eq!(m.name, "multirx.scan.handover_ms");
    assert!(!Selector::base("handover_ms").matches(&m));
    assert!(Selector::any().matches(&m));
}
