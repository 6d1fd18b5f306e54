//! What a signed radio link takes from the air (issue 22, item 19): only frames the peer
//! signed count, a frame of our own sent back is refused, and only the local radio's ids
//! move the signal figures the pilot sees.
//!
//! The attacker has no key; it transmits on the channel, so whatever it sends comes out of
//! our radio's serial port among the peer's frames, as the engines read them here.

use mavlink::MavlinkVersion;

use mavlora::Instant;
use mavlora::bridge::{Bridge, BridgeConfig};
use mavlora::dialect::{
    HEARTBEAT_DATA, MavAutopilot, MavMessage, MavType, RADIO_STATUS_DATA, SYSTEM_TIME_DATA,
};
use mavlora::filter::Profile;
use mavlora::quality::RssiScale;
use mavlora::schedule::SchedulerConfig;
use mavlora::signing::{LinkSigner, SigningConfig, SigningKey, SigningState};
use mavlora::wire::{OwnedFrame, Sender};

const KEY: SigningKey = SigningKey([5; 32]);
/// Signing time (10 µs units since 2015) of engine time zero, both ends' clocks agreeing.
const CLOCK: u64 = 300_000_000_000;

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

/// A bridge signing as link 1 (the router signs as 2), its state knowing the router from a
/// previous run (a fresh one takes nothing before the router answered its challenge).
fn signed_bridge() -> Bridge {
    let mut config = BridgeConfig::new(
        Profile::parse("", "test").unwrap(),
        SchedulerConfig {
            rate_bytes_per_s: 4000,
            burst_bytes: 1000,
            max_queued_bytes: 8000,
        },
    );
    config.signing = Some(SigningConfig {
        key: KEY,
        link_id: 1,
        epoch: CLOCK,
        state: {
            let mut state = SigningState::default();
            state.streams.insert((2, 0, 0), 1);
            state
        },
    });
    Bridge::new(config, Instant::ZERO).unwrap()
}

/// The ground side's frame number `seq`: a `SYSTEM_TIME` from the router's ids (255, 190),
/// which the bridge passes to the flight controller.
fn ground_frame(seq: u8) -> OwnedFrame {
    let mut s = Sender::new(255, 190, MavlinkVersion::V2);
    s.set_next_sequence(seq);
    s.frame(&MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
        time_unix_usec: u64::from(seq),
        ..Default::default()
    }))
}

fn radio_status(noise_dbm: i8) -> MavMessage {
    MavMessage::RADIO_STATUS(RADIO_STATUS_DATA {
        rssi: RssiScale::Sik.from_dbm(Some(-80)),
        noise: RssiScale::Sik.from_dbm(Some(noise_dbm)),
        remrssi: 255,
        remnoise: 255,
        ..RADIO_STATUS_DATA::default()
    })
}

/// Twenty frames from the router, five of them (5..=9) lost on the air, with an attacker's
/// unsigned frames in the router's name among them: `inject(seq)` gives what it sends after
/// the router's frame `seq`. Returns (frames counted received, frames counted lost).
fn loss_seen_with(inject: impl Fn(u8) -> Vec<OwnedFrame>) -> (u64, u64) {
    let mut bridge = signed_bridge();
    let mut router = LinkSigner::new(KEY, 2, CLOCK);
    for seq in 0..20u8 {
        let now = ms(10 * u64::from(seq));
        if !(5..=9).contains(&seq) {
            let signed = router.sign(&ground_frame(seq), now).unwrap();
            bridge.handle_radio_bytes(now, signed.as_bytes());
        }
        for f in inject(seq) {
            bridge.handle_radio_bytes(now, f.as_bytes());
        }
    }
    let stats = bridge.stats();
    assert_eq!(stats.signing.accepted, 15);
    (stats.radio_reader.frames(), stats.radio_reader.lost)
}

/// Frames with the router's ids and numbers of the attacker's choosing read as a link that
/// loses most of what it carries (each out-of-order number is up to 255 "lost"): the pilot
/// is told the downlink is degraded and redundancy turns on. The loss counted is the five
/// signed frames the air took, whatever was injected.
#[test]
fn unsigned_frames_in_the_peers_name_do_not_fake_loss() {
    let (received, lost) = loss_seen_with(|seq| vec![ground_frame(seq.wrapping_add(128))]);
    assert_eq!((received, lost), (15, 5));
}

/// The other way: the attacker fills the gap the air left with frames numbered 5..=9, so a
/// link that lost a quarter of its frames reads as clean.
#[test]
fn unsigned_frames_in_the_peers_name_do_not_hide_loss() {
    let (received, lost) = loss_seen_with(|seq| {
        if seq == 4 {
            (5..=9).map(ground_frame).collect()
        } else {
            Vec::new()
        }
    });
    assert_eq!((received, lost), (15, 5));
}

/// The bridge's own signed frame, recorded on the air and sent back to it 30 s later, is a
/// stream it never heard (its own ids, its own link id) within the spec's minute: it was
/// taken as the router's and passed to the flight controller.
#[test]
fn a_frame_the_bridge_signed_sent_back_to_it_is_refused() {
    let mut bridge = signed_bridge();
    let mut fc = Sender::new(1, 1, MavlinkVersion::V2);
    let heartbeat = fc.frame(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        ..HEARTBEAT_DATA::default()
    }));
    bridge.handle_fc_bytes(ms(0), heartbeat.as_bytes());
    bridge.handle_timeout(ms(10));
    let sent: Vec<OwnedFrame> =
        std::iter::from_fn(|| bridge.poll_radio_transmit(ms(10), usize::MAX)).collect();
    let recorded = sent
        .iter()
        .find(|f| f.system_id() == 1 && f.component_id() == 1)
        .expect("the autopilot's heartbeat went on the radio");
    assert!(recorded.is_signed());
    while bridge.poll_fc_transmit(ms(10)).is_some() {}

    bridge.handle_radio_bytes(ms(30_000), recorded.as_bytes());
    let to_fc: Vec<OwnedFrame> =
        std::iter::from_fn(|| bridge.poll_fc_transmit(ms(30_000))).collect();
    assert!(
        to_fc.iter().all(|f| f.system_id() != 1),
        "the bridge's own frame reached the autopilot: {to_fc:?}"
    );
    assert_eq!(bridge.stats().signing.reflected, 1);
    assert_eq!(bridge.stats().signing.accepted, 0);
}

/// SiK writes its own `RADIO_STATUS` into its serial output unsigned, as system '3'
/// component 'D'; an unsigned `RADIO_STATUS` with any other ids came from the air and moves
/// nothing (it used to set the noise floor and rssi the pilot sees). The router's signed
/// frames still count.
#[test]
fn only_the_local_radios_ids_set_the_signal_the_pilot_sees() {
    let mut bridge = signed_bridge();
    let mut stranger = Sender::new(1, 68, MavlinkVersion::V1);
    bridge.handle_radio_bytes(ms(10), stranger.frame(&radio_status(-50)).as_bytes());
    assert_eq!(
        bridge.quality().noise(),
        None,
        "a stranger set the noise floor"
    );
    let mut sik = Sender::new(b'3', b'D', MavlinkVersion::V1);
    bridge.handle_radio_bytes(ms(20), sik.frame(&radio_status(-104)).as_bytes());
    assert_eq!(bridge.quality().noise(), Some(-104));
    bridge.handle_radio_bytes(ms(30), stranger.frame(&radio_status(-50)).as_bytes());
    assert_eq!(bridge.quality().noise(), Some(-104));
    // Neither is a frame of the peer's.
    assert_eq!(bridge.stats().radio_reader.frames(), 0);
    assert_eq!(bridge.stats().signing.unsigned, 2);
}

/// Ten bytes announcing a 255-byte payload, sent without the key every 0.4 s, held every
/// frame behind them until 280 more bytes came (a command's ack 1.8 s late on LoRa). A frame
/// the router signed, inside the waiting candidate, now ends it at once: each command reaches
/// the flight controller in the read that brought it, and each forged header is counted.
#[test]
fn forged_long_headers_do_not_hold_the_peers_frames_back() {
    let mut bridge = signed_bridge();
    let mut router = LinkSigner::new(KEY, 2, CLOCK);
    let forged = [0xFD, 0xFF, 0, 0, 0, 255, 190, 0x1E, 0, 0];
    for k in 0..10u8 {
        let now = ms(400 * u64::from(k));
        bridge.handle_radio_bytes(now, &forged);
        let signed = router.sign(&ground_frame(k), now).unwrap();
        bridge.handle_radio_bytes(now, signed.as_bytes());
        let to_fc: Vec<OwnedFrame> = std::iter::from_fn(|| bridge.poll_fc_transmit(now))
            .filter(|f| f.system_id() == 255)
            .collect();
        assert_eq!(to_fc.len(), 1, "frame {k} held back");
    }
    let stats = bridge.stats();
    assert_eq!(stats.signing.accepted, 10);
    assert_eq!(stats.radio_reader.partials_dropped, 10);
}
