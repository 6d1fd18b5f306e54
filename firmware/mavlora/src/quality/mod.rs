//! Link quality in both directions: each side reports what it hears in `LINK_QUALITY`
//! (id 15) and learns what the other side hears; the router turns both into what any ground
//! station shows ([`LinkMonitor`]: `RADIO_STATUS` and `STATUSTEXT` alarms).

mod engine;
mod monitor;
mod rssi;
mod window;

pub use engine::{
    LOCAL_RADIO, LinkQuality, LinkQualityConfig, MONITOR_SHARE, PeerReport, PeerState,
    REPORT_BYTES, REPORT_BYTES_SIGNED, is_local_radio_status,
};
pub use monitor::{Direction, Health, LinkMonitor, MonitorConfig, Notice};
pub use rssi::RssiScale;
pub use window::LossWindow;
