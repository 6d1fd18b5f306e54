//! Turning a radio's RSSI report into dBm.

/// How to read the `rssi`/`remrssi` bytes of `RADIO_STATUS`, whose scale is device-specific.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RssiScale {
    /// SiK firmware (mRo, RFD900, 3DR radios): dBm = value / 1.9 − 127.
    Sik,
}

impl RssiScale {
    /// dBm for a raw value; `None` for the "unknown" value 255. Clamped to −128..=126 so it
    /// never collides with the `LINK_QUALITY` "unknown" marker (127).
    pub fn to_dbm(self, raw: u8) -> Option<i8> {
        if raw == u8::MAX {
            return None;
        }
        match self {
            Self::Sik => {
                let dbm = (f64::from(raw) / 1.9 - 127.0).round();
                Some(dbm.clamp(-128.0, 126.0) as i8)
            }
        }
    }
}

impl RssiScale {
    /// The raw value for `dbm` (`None`: 255, unknown), for a `RADIO_STATUS` we make.
    pub fn from_dbm(self, dbm: Option<i8>) -> u8 {
        let Some(dbm) = dbm else {
            return u8::MAX;
        };
        match self {
            Self::Sik => ((f64::from(dbm) + 127.0) * 1.9).round().clamp(0.0, 254.0) as u8,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sik_scale() {
        assert_eq!(RssiScale::Sik.to_dbm(0), Some(-127));
        assert_eq!(RssiScale::Sik.to_dbm(95), Some(-77)); // 95 / 1.9 = 50
        assert_eq!(RssiScale::Sik.to_dbm(254), Some(7));
        assert_eq!(RssiScale::Sik.to_dbm(255), None);
        assert_eq!(RssiScale::Sik.from_dbm(Some(-77)), 95);
        assert_eq!(RssiScale::Sik.from_dbm(Some(100)), 254);
        assert_eq!(RssiScale::Sik.from_dbm(None), 255);
    }
}
