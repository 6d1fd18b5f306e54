//! JUnit XML from a [`RunRecord`], for CI dashboards.
//!
//! One `<testsuite>` per rig run and one `<testcase>` per phase. A failed
//! phase's message lists each failing measurement as
//! `name = value unit (limit: x <= 50 ms)`. Every measurement, passing or
//! not, is also a `<property>` of its test case (`name` = value, plus
//! `name.unit`, `name.limits`, `name.outcome`), because JUnit has no place
//! for the values of passing checks and the evidence needs them.

use std::io;
use std::path::{Path, PathBuf};
use std::time::Duration;

use chrono::{DateTime, FixedOffset};
use quick_junit::{NonSuccessKind, Property, Report, TestCase, TestCaseStatus, TestSuite};

use crate::measurement::Measurement;
use crate::record::{PhaseOutcome, PhaseRecord, RunRecord};

/// File name of the JUnit report inside an output folder.
pub const JUNIT_FILE: &str = "junit.xml";

/// Renders `record` as `junit.xml` in `dir` and returns its path.
pub fn write_junit(record: &RunRecord, dir: &Path) -> io::Result<PathBuf> {
    let xml = render_junit(record)?;
    super::write_report(dir, JUNIT_FILE, &xml)
}

/// Renders `record` as a JUnit XML document.
pub fn render_junit(record: &RunRecord) -> io::Result<String> {
    let mut suite = TestSuite::new(record.rig.name.as_str());
    if let Some(t) = timestamp(&record.started) {
        suite.set_timestamp(t);
    }
    if let (Some(start), Some(end)) = (timestamp(&record.started), timestamp(&record.ended))
        && let Ok(d) = (end - start).to_std()
    {
        suite.set_time(d);
    }
    suite.add_properties(run_properties(record));
    for phase in &record.phases {
        suite.add_test_case(test_case(&record.rig.name, phase));
    }
    let mut report = Report::new("rig");
    if let Some(t) = timestamp(&record.started) {
        report.set_timestamp(t);
    }
    if let Some(t) = suite.time {
        report.set_time(t);
    }
    report.add_test_suite(suite);
    report.to_string().map_err(io::Error::other)
}

/// Who ran what with which rig and devices, as suite properties, so a
/// dashboard entry can be traced to its evidence.
fn run_properties(record: &RunRecord) -> Vec<Property> {
    let mut props = vec![
        Property::new("tool.name", record.tool.name.as_str()),
        Property::new("tool.version", record.tool.version.as_str()),
        Property::new(
            "tool.git_commit",
            record.tool.git_commit.as_deref().unwrap_or(""),
        ),
        Property::new("rig.file", record.rig.file.display().to_string()),
        Property::new("rig.sha256", record.rig.sha256.as_str()),
        Property::new("run.outcome", record.outcome.as_str()),
        Property::new("run.started", record.started.as_str()),
        Property::new("run.ended", record.ended.as_str()),
    ];
    for d in &record.devices {
        let p = |key: &str, value: &str| Property::new(format!("device.{}.{key}", d.role), value);
        props.push(p("kind", &d.kind));
        props.push(p("description", &d.description));
        if let Some(port) = &d.port {
            props.push(p("port", port));
        }
        if let Some(sha) = &d.firmware_sha256 {
            props.push(p("firmware_sha256", sha));
        }
    }
    props
}

fn test_case(rig_name: &str, phase: &PhaseRecord) -> TestCase {
    let status = match phase.outcome {
        PhaseOutcome::Pass => TestCaseStatus::success(),
        PhaseOutcome::Fail => {
            let lines: Vec<String> = phase.failing_measurements().map(failure_line).collect();
            let mut s = TestCaseStatus::non_success(NonSuccessKind::Failure);
            s.set_type("measurement");
            s.set_message(lines.join("; "));
            s.set_description(lines.join("\n"));
            s
        }
        PhaseOutcome::Error => {
            let error = phase.error.as_deref().unwrap_or("phase returned an error");
            let mut s = TestCaseStatus::non_success(NonSuccessKind::Error);
            s.set_type("error");
            s.set_message(error);
            let mut text = vec![error.to_owned()];
            text.extend(phase.failing_measurements().map(failure_line));
            s.set_description(text.join("\n"));
            s
        }
        PhaseOutcome::Interrupted => {
            let why = phase.error.as_deref().unwrap_or("the rig was stopped");
            let mut s = TestCaseStatus::non_success(NonSuccessKind::Error);
            s.set_type("interrupted");
            s.set_message(why);
            s
        }
        PhaseOutcome::Skipped => {
            let mut s = TestCaseStatus::skipped();
            if let Some(why) = &phase.error {
                s.set_message(why.as_str());
            }
            s
        }
    };
    let mut case = TestCase::new(phase.name.as_str(), status);
    case.set_classname(rig_name);
    if let Some(t) = timestamp(&phase.started) {
        case.set_timestamp(t);
    }
    if let Ok(d) = Duration::try_from_secs_f64(phase.duration_s) {
        case.set_time(d);
    }
    for m in &phase.measurements {
        case.add_properties(measurement_properties(m));
    }
    for a in &phase.attachments {
        case.add_property(Property::new(
            format!("attachment.{}", a.name),
            a.path.display().to_string(),
        ));
        case.add_property(Property::new(
            format!("attachment.{}.sha256", a.name),
            a.sha256.as_str(),
        ));
    }
    if !phase.log.is_empty() {
        case.set_system_out(phase.log.join("\n"));
    }
    case
}

/// `name = value unit (limit: x <= 50 ms)`, or `name = unset (...)`.
pub fn failure_line(m: &Measurement) -> String {
    let mut line = format!(
        "{} = {} (limit: {})",
        m.name,
        m.render_value(),
        m.limits.render(&m.unit)
    );
    if let Some(note) = &m.note {
        line.push_str(&format!(" [{note}]"));
    }
    line
}

fn measurement_properties(m: &Measurement) -> Vec<Property> {
    let value = m.value.map(|v| v.to_string()).unwrap_or_default();
    let mut props = vec![
        Property::new(m.name.as_str(), value),
        Property::new(format!("{}.unit", m.name), m.unit.as_str()),
        Property::new(format!("{}.limits", m.name), m.limits.render(&m.unit)),
        Property::new(format!("{}.outcome", m.name), m.outcome.as_str()),
    ];
    if let Some(note) = &m.note {
        props.push(Property::new(format!("{}.note", m.name), note.as_str()));
    }
    props
}

fn timestamp(rfc3339: &str) -> Option<DateTime<FixedOffset>> {
    DateTime::parse_from_rfc3339(rfc3339).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::tests::sample_record;

    fn props(case: &TestCase) -> Vec<(&str, &str)> {
        case.properties
            .iter()
            .map(|p| (p.name.as_str(), p.value.as_str()))
            .collect()
    }

    #[test]
    fn xml_is_well_formed() {
        let xml = render_junit(&sample_record()).unwrap();
        let mut reader = quick_xml::Reader::from_str(&xml);
        let mut elements = 0;
        loop {
            match reader.read_event() {
                Ok(quick_xml::events::Event::Eof) => break,
                Ok(quick_xml::events::Event::Start(_) | quick_xml::events::Event::Empty(_)) => {
                    elements += 1
                }
                Ok(_) => {}
                Err(e) => panic!("malformed XML at {}: {e}\n{xml}", reader.error_position()),
            }
        }
        assert!(elements > 10, "{xml}");
    }

    #[test]
    fn one_suite_one_case_per_phase_with_failure_text() {
        let record = sample_record();
        let xml = render_junit(&record).unwrap();
        let report = Report::deserialize_from_str(&xml).unwrap();
        assert_eq!(report.test_suites.len(), 1);
        let suite = &report.test_suites[0];
        assert_eq!(suite.name.as_str(), "emulated");
        assert_eq!(suite.tests, 4);
        assert_eq!((suite.failures, suite.errors, suite.skipped), (1, 1, 1));
        let names: Vec<_> = suite.test_cases.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "mux.parallel.scenario_b",
                "link.bridge.bandwidth",
                "link.mission_upload",
                "mux.scan.scenario_c"
            ]
        );
        let TestCaseStatus::NonSuccess { kind, message, .. } = &suite.test_cases[1].status else {
            panic!("phase 2 should fail: {:?}", suite.test_cases[1].status);
        };
        assert_eq!(*kind, NonSuccessKind::Failure);
        assert_eq!(
            message.as_ref().unwrap().as_str(),
            "link.pty.sik_64k.bytes_per_s = 1200 B/s (limit: x <= 951 B/s); \
             link.pty.position_rate = unset (limit: x >= 3 Hz)"
        );
        let TestCaseStatus::NonSuccess { kind, message, .. } = &suite.test_cases[2].status else {
            panic!("phase 3 should error");
        };
        assert_eq!(*kind, NonSuccessKind::Error);
        assert_eq!(
            message.as_ref().unwrap().as_str(),
            "router exited with status 1 <&>"
        );
        assert!(matches!(
            suite.test_cases[3].status,
            TestCaseStatus::Skipped { .. }
        ));
    }

    #[test]
    fn passing_measurements_are_properties() {
        let xml = render_junit(&sample_record()).unwrap();
        let report = Report::deserialize_from_str(&xml).unwrap();
        let case = &report.test_suites[0].test_cases[0];
        let p = props(case);
        for want in [
            ("mux.parallel.handover_ms", "12.5"),
            ("mux.parallel.handover_ms.unit", "ms"),
            ("mux.parallel.handover_ms.limits", "x <= 50 ms"),
            ("mux.parallel.handover_ms.outcome", "pass"),
            ("mux.scan.handover_ms.outcome", "marginal"),
            ("attachment.fc-capture", "mux.parallel.scenario_b/fc.sbus"),
        ] {
            assert!(p.contains(&want), "{want:?} not in {p:?}");
        }
        assert_eq!(
            case.system_out.as_ref().unwrap().as_str(),
            "TX 1 off at t=2.000 s"
        );
        let suite_props: Vec<_> = report.test_suites[0]
            .properties
            .iter()
            .map(|p| (p.name.as_str(), p.value.as_str()))
            .collect();
        assert!(suite_props.contains(&("tool.git_commit", "0123abcd")));
        assert!(suite_props.contains(&("device.mux.port", "/dev/pts/7")));
    }
}
