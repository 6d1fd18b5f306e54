//! The MavLora profiles shipped in `profiles/`, built in so simulations do not depend on the
//! working directory.

/// `profiles/px4-normal.toml`: the paper's limiting and filtering.
pub const PX4_NORMAL_TOML: &str =
    include_str!("../../../firmware/mavlora/profiles/px4-normal.toml");

/// `profiles/px4-compact.toml`: for compact telemetry.
pub const PX4_COMPACT_TOML: &str =
    include_str!("../../../firmware/mavlora/profiles/px4-compact.toml");

/// `profiles/ardupilot-mavlink1.toml`: limiting (stream groups) and filtering for a MAVLink 1
/// ArduPilot.
pub const ARDUPILOT_MAVLINK1_TOML: &str =
    include_str!("../../../firmware/mavlora/profiles/ardupilot-mavlink1.toml");

/// `profiles/ardupilot-compact.toml`: compact telemetry from a MAVLink 1 ArduPilot.
pub const ARDUPILOT_COMPACT_TOML: &str =
    include_str!("../../../firmware/mavlora/profiles/ardupilot-compact.toml");

/// A profile with only its `stream_hz` lines: stream limiting at the flight controller, no
/// radio filtering (the paper's "gcs fc limit" run).
pub fn stream_only(profile: &str) -> String {
    profile
        .lines()
        .filter(|l| !l.trim_start().starts_with("radio"))
        .collect::<Vec<_>>()
        .join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlora::filter::Profile;

    #[test]
    fn built_in_profiles_parse_and_stream_only_keeps_no_radio_rule() {
        Profile::parse(PX4_NORMAL_TOML, "px4-normal.toml").unwrap();
        Profile::parse(PX4_COMPACT_TOML, "px4-compact.toml").unwrap();
        Profile::parse(ARDUPILOT_MAVLINK1_TOML, "ardupilot-mavlink1.toml").unwrap();
        Profile::parse(ARDUPILOT_COMPACT_TOML, "ardupilot-compact.toml").unwrap();
        let limit = stream_only(PX4_NORMAL_TOML);
        Profile::parse(&limit, "limit").unwrap();
        assert!(!limit.lines().any(|l| l.trim_start().starts_with("radio")));
        assert!(limit.contains("stream_hz = 3"));
    }
}
