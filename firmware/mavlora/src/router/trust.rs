//! Who may talk to the vehicle from the ground side.
//!
//! The radio peer is trusted by the link key (`--key`, [`crate::signing`]); everything the
//! router forwards from the ground is signed with that key on its way out, so the ground side
//! needs its own gate or the key protects nothing. [`GroundPolicy`] is that gate:
//!
//! - a source **address** must be in `allow` (IP networks; the port is not part of it, a ground
//!   station restarted on another port is the same station): a datagram or TCP chunk from
//!   elsewhere is rejected whole, before any of it is parsed;
//! - each frame's **system id** must be in `allow_sysid` (the standard ground stations':
//!   255 for QGroundControl, Mission Planner and MAVProxy, 245 for MAVSDK): frames from others
//!   are rejected one by one;
//! - each source (address) has at most `commands_in_flight` commands being relayed at once, so
//!   one sender cannot fill the radio's priority queue and push another's commands out.
//!
//! - with a ground key (`--ground-key`, MAVLink 2 signing between ground station and router,
//!   not the radio's key), each frame must carry a valid, fresh signature: this is the only
//!   check here that authenticates a sender rather than trusting where it says it is from.
//!
//! Only a checksum-valid frame that passed these checks teaches the router its UDP peer
//! ([`GroundInput::learn_peer`]): a stray or hostile datagram never redirects telemetry.
//! Rejections are counted ([`TrustStats`]) and reported once per source and reason per
//! [`GroundPolicy::log_every`] (the IO layer logs them).

use crate::time::Duration;
use std::fmt;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr};
use std::str::FromStr;

/// An IP network: an address and a prefix length (`10.0.0.0/24`, `127.0.0.1`, `::1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Deserialize)]
#[serde(try_from = "String")]
pub struct IpNet {
    addr: IpAddr,
    prefix: u8,
}

/// A network that does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum IpNetError {
    /// The part before `/` is not an IP address.
    #[error("`{0}` is not an IP address (expected e.g. 127.0.0.1 or 10.0.0.0/24)")]
    Address(String),
    /// The prefix length is not a number up to 32 (IPv4) or 128 (IPv6).
    #[error("`{0}` is not a prefix length for this address (0..=32 for IPv4, 0..=128 for IPv6)")]
    Prefix(String),
}

impl IpNet {
    /// `addr/prefix`; `None` if the prefix is longer than the address.
    pub fn new(addr: IpAddr, prefix: u8) -> Option<Self> {
        let max = if addr.is_ipv4() { 32 } else { 128 };
        (prefix <= max).then_some(Self { addr, prefix })
    }

    /// Whether `ip` is in this network (an IPv4-mapped IPv6 address counts as its IPv4 one).
    pub fn contains(&self, ip: IpAddr) -> bool {
        let ip = match ip {
            IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(ip, IpAddr::V4),
            v4 => v4,
        };
        match (self.addr, ip) {
            (IpAddr::V4(net), IpAddr::V4(ip)) => {
                let mask = u32::MAX
                    .checked_shl(32 - u32::from(self.prefix))
                    .unwrap_or(0);
                u32::from(net) & mask == u32::from(ip) & mask
            }
            (IpAddr::V6(net), IpAddr::V6(ip)) => {
                let mask = u128::MAX
                    .checked_shl(128 - u32::from(self.prefix))
                    .unwrap_or(0);
                u128::from(net) & mask == u128::from(ip) & mask
            }
            _ => false,
        }
    }
}

impl FromStr for IpNet {
    type Err = IpNetError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (addr, prefix) = s.split_once('/').map_or((s, None), |(a, p)| (a, Some(p)));
        let addr: IpAddr = addr
            .trim()
            .parse()
            .map_err(|_| IpNetError::Address(s.to_owned()))?;
        let prefix = match prefix {
            None if addr.is_ipv4() => 32,
            None => 128,
            Some(p) => p
                .trim()
                .parse()
                .map_err(|_| IpNetError::Prefix(s.to_owned()))?,
        };
        Self::new(addr, prefix).ok_or_else(|| IpNetError::Prefix(s.to_owned()))
    }
}

impl TryFrom<String> for IpNet {
    type Error = IpNetError;

    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

impl fmt::Display for IpNet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.addr, self.prefix)
    }
}

/// The ground side's trust policy (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct GroundPolicy {
    /// Source networks allowed to reach the vehicle and become the UDP peer.
    pub allow: Vec<IpNet>,
    /// System ids whose frames are forwarded to the radio.
    pub allow_sysid: Vec<u8>,
    /// Commands one source may have in the relay at once; more are dropped (counted).
    pub commands_in_flight: usize,
    /// At most one rejection report per source and reason per this period.
    pub log_every: Duration,
}

impl Default for GroundPolicy {
    /// This host only (`127.0.0.1`, `::1`: not all of `127.0.0.0/8`, a local process
    /// has to choose another loopback address to be rejected, and tests do); system ids 255
    /// (QGroundControl, MAVProxy, Mission Planner, pymavlink's default) and 245 (MAVSDK's
    /// ground station), so the standard ground stations work out of the box; 4 commands in
    /// flight per source.
    fn default() -> Self {
        Self {
            allow: vec![
                IpNet::new(Ipv4Addr::LOCALHOST.into(), 32).expect("valid"),
                IpNet::new(Ipv6Addr::LOCALHOST.into(), 128).expect("valid"),
            ],
            allow_sysid: vec![255, 245],
            commands_in_flight: 4,
            log_every: Duration::from_secs(10),
        }
    }
}

impl GroundPolicy {
    /// Whether `ip` may talk to the vehicle.
    pub fn allows_address(&self, ip: IpAddr) -> bool {
        self.allow.iter().any(|n| n.contains(ip))
    }

    /// Whether frames from system `id` may go to the radio.
    pub fn allows_system(&self, id: u8) -> bool {
        self.allow_sysid.contains(&id)
    }
}

/// Why something from the ground did not reach the radio.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GroundRejection {
    /// The source address is not in `allow`.
    Address,
    /// The frame's system id is not in `allow_sysid` (the id).
    SystemId(u8),
    /// The source already has `commands_in_flight` commands in the relay.
    CommandBudget,
    /// Ground signing is on and the frame is unsigned, badly signed, replayed or stamped
    /// more than a minute ahead of our clock.
    Signature,
}

impl fmt::Display for GroundRejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Address => f.write_str("source address not allowed"),
            Self::SystemId(id) => write!(f, "system id {id} not allowed"),
            Self::CommandBudget => f.write_str("too many commands in flight from this source"),
            Self::Signature => f.write_str(
                "not signed with the ground key, replayed, or stamped over a minute ahead of our clock",
            ),
        }
    }
}

/// Counters of the ground-side gate.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TrustStats {
    /// Datagrams (TCP: chunks) from addresses not allowed, dropped whole.
    pub rejected_address: u64,
    /// Frames from system ids not allowed.
    pub rejected_sysid: u64,
    /// Commands over their source's in-flight budget.
    pub rejected_budget: u64,
    /// Frames not signed with the ground key, badly signed or replayed (ground signing on).
    pub rejected_signature: u64,
}

impl TrustStats {
    /// Everything rejected (`ground_rejected` on the status line).
    pub fn total(&self) -> u64 {
        self.rejected_address + self.rejected_sysid + self.rejected_budget + self.rejected_signature
    }

    pub(crate) fn count(&mut self, why: GroundRejection) {
        match why {
            GroundRejection::Address => self.rejected_address += 1,
            GroundRejection::SystemId(_) => self.rejected_sysid += 1,
            GroundRejection::CommandBudget => self.rejected_budget += 1,
            GroundRejection::Signature => self.rejected_signature += 1,
        }
    }
}

/// What became of one datagram (or TCP chunk) from the ground.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GroundInput {
    /// Checksum-valid frames that passed the policy.
    pub accepted: usize,
    /// Frames (or the whole datagram) rejected.
    pub rejected: usize,
    /// The first reason, when a report is due for this source and reason (rate-limited by
    /// [`GroundPolicy::log_every`]): the IO layer logs it.
    pub report: Option<GroundRejection>,
    /// What to tell the source, with the report: a `STATUSTEXT` saying why it was refused,
    /// for the IO layer to send to that source alone (it is not a peer, so nothing else
    /// reaches it). Only for a system id not allowed or commands over budget: a stranger (an
    /// address not allowed, or a sender without the ground key) is told nothing.
    pub reply: Option<crate::wire::OwnedFrame>,
}

impl GroundInput {
    /// Whether the sender may become the UDP peer: it sent a valid, allowed frame.
    pub fn learn_peer(&self) -> bool {
        self.accepted > 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression: MAVSDK's ground station (system id 245) was refused by default, so its
    /// missions and commands timed out.
    #[test]
    fn the_standard_ground_stations_are_allowed_by_default() {
        let p = GroundPolicy::default();
        for (station, id) in [
            ("QGroundControl, MAVProxy, Mission Planner", 255),
            ("MAVSDK", 245),
        ] {
            assert!(p.allows_system(id), "{station}");
        }
        assert!(
            !p.allows_system(1),
            "an autopilot's id is not a ground station's"
        );
        assert!(!p.allows_system(0));
    }

    fn ip(s: &str) -> IpAddr {
        s.parse().unwrap()
    }

    #[test]
    fn networks_parse_and_match() {
        let lan: IpNet = "10.0.0.0/24".parse().unwrap();
        assert!(lan.contains(ip("10.0.0.7")));
        assert!(!lan.contains(ip("10.0.1.7")));
        assert!(lan.contains(ip("::ffff:10.0.0.9")), "IPv4-mapped IPv6");
        let one: IpNet = "127.0.0.1".parse().unwrap();
        assert!(one.contains(ip("127.0.0.1")));
        assert!(!one.contains(ip("127.0.0.2")));
        let any: IpNet = "0.0.0.0/0".parse().unwrap();
        assert!(any.contains(ip("192.0.2.1")));
        assert!(!any.contains(ip("::2")));
        assert_eq!("::1".parse::<IpNet>().unwrap().to_string(), "::1/128");
        assert!(matches!(
            "10.0.0.0/33".parse::<IpNet>(),
            Err(IpNetError::Prefix(_))
        ));
        assert!(matches!(
            "localhost".parse::<IpNet>(),
            Err(IpNetError::Address(_))
        ));
    }

    #[test]
    fn the_default_policy_is_loopback_and_sysid_255() {
        let p = GroundPolicy::default();
        assert!(p.allows_address(ip("127.0.0.1")));
        assert!(p.allows_address(ip("::1")));
        assert!(!p.allows_address(ip("127.0.0.2")));
        assert!(!p.allows_address(ip("192.168.1.20")));
        assert!(p.allows_system(255));
        assert!(!p.allows_system(1));
    }
}
