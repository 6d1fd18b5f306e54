//! The bridge and router engines fed arbitrary bytes from both of their sides at arbitrary
//! times, wired to each other through a lossless wire. Invariants, on every input:
//! - nothing panics;
//! - with signing on, every frame either engine puts on the radio carries a valid signature
//!   with the link key (checked by an independent verifier, a `LinkSigner` of our own), so
//!   nothing unsigned ever reaches the radio, whatever the flight controller or ground sent;
//! - neither engine hands the radio more bytes than its budget allows: at most the burst plus
//!   the rate times the elapsed time (the token bucket's promise).
//!
//! Inputs of odd length run the bridge with compact telemetry (its frames, made of whatever
//! the flight controller sent, are expanded by the router), even ones without.

use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::compact::CompactConfig;
use mavlora::filter::Profile;
use mavlora::router::{Router, RouterConfig};
use mavlora::schedule::SchedulerConfig;
use mavlora::signing::{SigningConfig, SigningKey};
use mavlora::wire::{FrameReader, Integrity, known};
use mavlora::{Duration, Instant};

const RATE: u32 = 683;
const BURST: u32 = 600;
const PROFILE: &str = include_str!("../../profiles/px4-normal.toml");

struct Budget {
    start: Instant,
    sent: u64,
}

impl Budget {
    fn check(&mut self, now: Instant, bytes: usize, who: &str) {
        self.sent += bytes as u64;
        let elapsed = now.saturating_duration_since(self.start).as_secs_f64();
        let allowed = f64::from(BURST) + f64::from(RATE) * elapsed + 1.0;
        assert!(
            self.sent as f64 <= allowed,
            "{who} sent {} B in {elapsed} s (budget {allowed})",
            self.sent
        );
    }
}

fn key() -> SigningKey {
    SigningKey::parse(b"000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f")
        .expect("test key")
}

fn signing(link_id: u8) -> SigningConfig {
    SigningConfig {
        key: key(),
        link_id,
        epoch: 1_000_000,
        state: Default::default(),
    }
}

/// Every frame on the radio must verify with the key (an independent signer per sender, so
/// replay tracking does not cross the two directions).
fn assert_signed(
    checker: &mut mavlora::signing::LinkSigner,
    bytes: &[u8],
    now: Instant,
    who: &str,
) {
    let mut reader = FrameReader::new();
    reader.push(bytes);
    reader.finish();
    while let Some(rx) = reader.next_frame() {
        // Unknown message ids pass (the profiles' default) and no reader can check their
        // checksum: they come out `Unchecked`, and their signature is what vouches for them.
        assert!(
            rx.integrity == Integrity::Checked || known::crc_extra(rx.frame.message_id()).is_none(),
            "{who} sent a damaged frame"
        );
        assert!(
            checker.verify(&rx.frame, now).is_ok(),
            "{who} put an unsigned or badly signed frame on the radio: {:02x?}",
            rx.frame.as_bytes()
        );
    }
}

pub fn run(data: &[u8]) {
    let start = Instant::ZERO;
    let scheduler = SchedulerConfig::for_radio(RATE, BURST);
    let profile = Profile::parse(PROFILE, "px4-normal.toml").expect("shipped profile");
    let mut bconf = BridgeConfig::new(profile, scheduler);
    bconf.signing = Some(signing(1));
    if data.len() % 2 == 1 {
        bconf.compact = Some(CompactConfig::default());
    }
    let mut rconf = RouterConfig::new(scheduler);
    rconf.signing = Some(signing(2));
    let mut bridge = Bridge::new(bconf, start).expect("bridge");
    let mut router = Router::new(rconf, start).expect("router");
    let (mut bridge_budget, mut router_budget) =
        (Budget { start, sent: 0 }, Budget { start, sent: 0 });
    let mut check_bridge = signing(9).signer();
    let mut check_router = signing(9).signer();
    let mut now = start;
    // Input: records of [op, advance_ms, len, bytes...].
    let mut rest = data;
    while let [op, advance, len, tail @ ..] = rest {
        let n = usize::from(*len).min(tail.len());
        let (bytes, next) = tail.split_at(n);
        rest = next;
        now += Duration::from_millis(u64::from(*advance) * 4);
        match op % 6 {
            0 => bridge.handle_fc_bytes(now, bytes),
            1 => {
                let _ = router.handle_gcs_bytes(now, bytes);
            }
            2 => bridge.handle_radio_bytes(now, bytes),
            3 => router.handle_radio_bytes(now, bytes),
            4 => bridge.handle_fc_idle(now),
            _ => router.handle_radio_idle(now),
        }
        bridge.handle_timeout(now);
        router.handle_timeout(now);
        while let Some(frame) = bridge.poll_radio_transmit(now, 4096) {
            bridge_budget.check(now, frame.as_bytes().len(), "bridge");
            assert_signed(&mut check_bridge, frame.as_bytes(), now, "bridge");
            router.handle_radio_bytes(now, frame.as_bytes());
        }
        while let Some(frame) = router.poll_radio_transmit(now, 4096) {
            router_budget.check(now, frame.as_bytes().len(), "router");
            assert_signed(&mut check_router, frame.as_bytes(), now, "router");
            bridge.handle_radio_bytes(now, frame.as_bytes());
        }
        while bridge.poll_fc_transmit(now).is_some() {}
        while router.poll_gcs_transmit().is_some() {}
    }
}
