//! The rig file's `[attenuator]` table (proposed; the rig file loader does not read it
//! yet):
//!
//! ```toml
//! [attenuator]
//! kind = "minicircuits"
//! address = "192.168.1.10"
//! transport = "telnet"     # or "http"; default telnet
//! # port = 23              # default: 23 for telnet, 80 for http
//! settle_ms = 1            # default: 1 (the units switch in under 1 µs)
//! timeout_ms = 2000        # default: 2000
//! # For a model the driver's table does not know (both or neither):
//! # range_db = [0.0, 90.0]
//! # step_db = 0.25
//! ```
//!
//! or, in CI, an emulated unit on 127.0.0.1:
//!
//! ```toml
//! [attenuator]
//! kind = "emulated"
//! model = "RCDAT-6000-90"  # default
//! serial = "EMULATED-0001" # default
//! ```

use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::DbRange;
use super::emulated::EmulatedSpec;
use super::minicircuits::{self, ModelSpec, Options, Transport};

/// The `[attenuator]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum AttenuatorConfig {
    /// A Mini-Circuits RUDAT/RCDAT unit on the bench network.
    Minicircuits(MinicircuitsConfig),
    /// The emulated unit ([`super::emulated`]).
    Emulated(EmulatedConfig),
}

/// `kind = "minicircuits"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MinicircuitsConfig {
    /// Host name or IP address.
    pub address: String,
    #[serde(default)]
    pub transport: Transport,
    /// TCP port; default the transport's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub port: Option<u16>,
    /// Wait after each setting, ms.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle_ms: Option<u64>,
    /// Longest wait for an answer, ms.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub timeout_ms: Option<u64>,
    /// `[min, max]` dB, for a model the table does not know; with `step_db`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_db: Option<[f64; 2]>,
    /// Step, dB; with `range_db`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub step_db: Option<f64>,
}

/// `kind = "emulated"`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmulatedConfig {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub serial: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle_ms: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub timeout_ms: Option<u64>,
}

/// A table that parses but cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// Only one of `range_db` and `step_db` is given.
    #[error("[attenuator]: range_db and step_db go together (give both or neither)")]
    HalfSpec,
    /// The range or step does not make sense.
    #[error("[attenuator]: range_db must be [min, max] with 0 <= min < max and step_db > 0")]
    BadSpec,
}

impl MinicircuitsConfig {
    /// The driver's options.
    pub fn options(&self) -> Result<Options, ConfigError> {
        let range_step = match (self.range_db, self.step_db) {
            (None, None) => None,
            (Some([min, max]), Some(step_db)) => {
                if !(0.0 <= min
                    && min < max
                    && max.is_finite()
                    && step_db > 0.0
                    && step_db.is_finite())
                {
                    return Err(ConfigError::BadSpec);
                }
                Some(ModelSpec {
                    range: DbRange { min, max },
                    step_db,
                })
            }
            _ => return Err(ConfigError::HalfSpec),
        };
        Ok(Options {
            host: self.address.clone(),
            port: self.port,
            transport: self.transport,
            timeout: self
                .timeout_ms
                .map_or(minicircuits::DEFAULT_TIMEOUT, Duration::from_millis),
            settle: self
                .settle_ms
                .map_or(minicircuits::DEFAULT_SETTLE, Duration::from_millis),
            range_step,
        })
    }
}

impl EmulatedConfig {
    /// The emulated unit's identity; honest, starting at 0 dB.
    pub fn spec(&self) -> EmulatedSpec {
        let default = EmulatedSpec::default();
        EmulatedSpec {
            model: self.model.clone().unwrap_or(default.model),
            serial: self.serial.clone().unwrap_or(default.serial),
            ..default
        }
    }

    /// The wait after each setting.
    pub fn settle(&self) -> Duration {
        self.settle_ms
            .map_or(minicircuits::DEFAULT_SETTLE, Duration::from_millis)
    }

    /// The longest wait for an answer.
    pub fn timeout(&self) -> Duration {
        self.timeout_ms
            .map_or(minicircuits::DEFAULT_TIMEOUT, Duration::from_millis)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Rig {
        attenuator: AttenuatorConfig,
    }

    /// The ```toml blocks of this module's doc, so the doc cannot drift from the schema.
    fn doc_toml_blocks() -> Vec<String> {
        let mut blocks = Vec::new();
        let mut block: Option<String> = None;
        for line in include_str!("config.rs")
            .lines()
            .filter_map(|l| l.strip_prefix("//!"))
        {
            let line = line.strip_prefix(' ').unwrap_or(line);
            match (&mut block, line) {
                (None, "```toml") => block = Some(String::new()),
                (Some(_), "```") => blocks.extend(block.take()),
                (Some(b), l) => {
                    b.push_str(l);
                    b.push('\n');
                }
                (None, _) => {}
            }
        }
        blocks
    }

    fn parse(s: &str) -> Result<AttenuatorConfig, toml::de::Error> {
        toml::from_str::<Rig>(s).map(|r| r.attenuator)
    }

    /// The examples in this module's doc, uncommented, parse to what they say.
    #[test]
    fn the_documented_tables_parse() {
        let blocks = doc_toml_blocks();
        assert_eq!(blocks.len(), 2, "{blocks:?}");
        // The bench example as written, then with its commented-out keys taken in.
        let as_written = parse(&blocks[0]).expect("parses");
        let AttenuatorConfig::Minicircuits(m) = &as_written else {
            panic!("{as_written:?}")
        };
        assert_eq!((m.port, m.range_db, m.step_db), (None, None, None));
        let uncommented: String = blocks[0]
            .lines()
            .map(|l| {
                l.strip_prefix("# ")
                    .filter(|k| k.contains(" = "))
                    .unwrap_or(l)
            })
            .map(|l| format!("{l}\n"))
            .collect();
        let bench = parse(&uncommented).expect("parses");
        let AttenuatorConfig::Minicircuits(m) = &bench else {
            panic!("{bench:?}")
        };
        let o = m.options().expect("usable");
        assert_eq!(o.host, "192.168.1.10");
        assert_eq!(o.port, Some(23));
        assert_eq!(o.transport, Transport::Telnet);
        assert_eq!(o.settle, Duration::from_millis(1));
        assert_eq!(o.timeout, Duration::from_secs(2));
        assert_eq!(
            o.range_step,
            Some(ModelSpec {
                range: DbRange {
                    min: 0.0,
                    max: 90.0
                },
                step_db: 0.25
            })
        );

        let ci = parse(&blocks[1]).expect("parses");
        assert_eq!(
            ci,
            AttenuatorConfig::Emulated(EmulatedConfig {
                model: Some("RCDAT-6000-90".into()),
                serial: Some("EMULATED-0001".into()),
                ..EmulatedConfig::default()
            })
        );
        let AttenuatorConfig::Emulated(e) = ci else {
            unreachable!()
        };
        assert_eq!(e.spec().model, "RCDAT-6000-90");
        assert_eq!(e.settle(), minicircuits::DEFAULT_SETTLE);
    }

    #[test]
    fn defaults_fill_in() {
        let c = parse(
            "[attenuator]\nkind = \"minicircuits\"\naddress = \"att1.lab\"\ntransport = \"http\"\n",
        )
        .expect("parses");
        let AttenuatorConfig::Minicircuits(m) = c else {
            panic!()
        };
        let o = m.options().expect("usable");
        assert_eq!(o.transport, Transport::Http);
        assert_eq!(o.port, None);
        assert_eq!(o.timeout, minicircuits::DEFAULT_TIMEOUT);
        assert_eq!(o.settle, minicircuits::DEFAULT_SETTLE);
        assert_eq!(o.range_step, None);
    }

    #[test]
    fn unknown_fields_kinds_and_transports_are_refused() {
        let typo = parse("[attenuator]\nkind = \"minicircuits\"\naddress = \"a\"\nsettle = 5\n");
        assert!(typo.unwrap_err().to_string().contains("settle"));
        assert!(parse("[attenuator]\nkind = \"emulated\"\naddress = \"a\"\n").is_err());
        assert!(parse("[attenuator]\nkind = \"keysight\"\naddress = \"a\"\n").is_err());
        assert!(
            parse("[attenuator]\nkind = \"minicircuits\"\naddress = \"a\"\ntransport = \"usb\"\n")
                .is_err()
        );
    }

    #[test]
    fn range_and_step_go_together() {
        let half = MinicircuitsConfig {
            address: "a".into(),
            transport: Transport::Telnet,
            port: None,
            settle_ms: None,
            timeout_ms: None,
            range_db: Some([0.0, 90.0]),
            step_db: None,
        };
        assert_eq!(half.options(), Err(ConfigError::HalfSpec));
        let bad = MinicircuitsConfig {
            step_db: Some(0.0),
            ..half.clone()
        };
        assert_eq!(bad.options(), Err(ConfigError::BadSpec));
        let upside_down = MinicircuitsConfig {
            range_db: Some([90.0, 0.0]),
            step_db: Some(0.25),
            ..half
        };
        assert_eq!(upside_down.options(), Err(ConfigError::BadSpec));
    }
}
