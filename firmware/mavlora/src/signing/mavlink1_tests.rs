//! A MAVLink 1 autopilot (ArduPilot on serial) behind the bridge, the router on the ground:
//! its frames cross the radio as MAVLink 2, signed, renumbered, and the ground's come back
//! to it as MAVLink 1.

use mavlink::MavlinkVersion;

use crate::bridge::{Bridge, BridgeConfig};
use crate::dialect::{
    ATTITUDE_DATA, COMMAND_LONG_DATA, HEARTBEAT_DATA, MavAutopilot, MavCmd, MavMessage, MavType,
};
use crate::filter::Profile;
use crate::router::{Router, RouterConfig};
use crate::schedule::SchedulerConfig;
use crate::signing::{SigningConfig, SigningKey, SigningState};
use crate::testutil::raw_frame;
use crate::time::{Duration, Instant};
use crate::wire::{FrameReader, OwnedFrame, Sender, ids};

/// ArduPilot's SIMSTATE: id 164, CRC_EXTRA 154 (ardupilotmega.xml), not in our dialect.
const SIMSTATE: u32 = 164;
const SIMSTATE_EXTRA: u8 = 154;

fn budget() -> SchedulerConfig {
    SchedulerConfig {
        rate_bytes_per_s: 20_000,
        burst_bytes: 4_000,
        max_queued_bytes: 16_000,
    }
}

/// Each end's state knows its peer (link 1 and 2) from a previous run: no handshake (a
/// fresh pair's first frames wait for it), every frame counts.
fn signing(link_id: u8) -> Option<SigningConfig> {
    let mut state = SigningState::default();
    state.streams.insert((3 - link_id, 0, 0), 1);
    Some(SigningConfig {
        key: SigningKey([9; 32]),
        link_id,
        epoch: 3_000_000_000,
        state,
    })
}

struct Pair {
    bridge: Bridge,
    router: Router,
    fc: Sender,
    /// Every frame that went on the radio, both ways.
    radio: Vec<OwnedFrame>,
    /// What the ground station and the flight controller received.
    gcs: Vec<OwnedFrame>,
    to_fc: Vec<OwnedFrame>,
    simstate_seq: u8,
}

impl Pair {
    fn new(signed: bool) -> Self {
        let mut b = BridgeConfig::new(Profile::parse("", "all passes").unwrap(), budget());
        let mut r = RouterConfig::new(budget());
        if signed {
            b.signing = signing(1);
            r.signing = signing(2);
        }
        Self {
            bridge: Bridge::new(b, Instant::ZERO).unwrap(),
            router: Router::new(r, Instant::ZERO).unwrap(),
            fc: Sender::new(1, 1, MavlinkVersion::V1),
            radio: Vec::new(),
            gcs: Vec::new(),
            to_fc: Vec::new(),
            simstate_seq: 0,
        }
    }

    /// One 100 ms tick of the FC's telemetry (MAVLink 1), then everything moved along.
    fn tick(&mut self, now: Instant) {
        let hb = self.fc.frame(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            ..Default::default()
        }));
        let att = self.fc.frame(&MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: now.as_millis() as u32 + 1,
            roll: 0.25,
            ..Default::default()
        }));
        // the FC's sequence runs on: what the bridge passes is a subset of its stream
        self.simstate_seq = self.simstate_seq.wrapping_add(3);
        let mut sim = raw_frame(
            MavlinkVersion::V1,
            1,
            1,
            self.simstate_seq,
            SIMSTATE,
            &[0x11; 44],
        );
        sim.fill_checksum(SIMSTATE_EXTRA);
        for f in [hb, att, sim] {
            self.bridge.handle_fc_bytes(now, f.as_bytes());
        }
        self.pump(now);
    }

    fn pump(&mut self, now: Instant) {
        self.bridge.handle_timeout(now);
        while let Some(f) = self.bridge.poll_radio_transmit(now, usize::MAX) {
            self.router.handle_radio_bytes(now, f.as_bytes());
            self.radio.push(f);
        }
        self.router.handle_timeout(now);
        while let Some(f) = self.router.poll_radio_transmit(now, usize::MAX) {
            self.bridge.handle_radio_bytes(now, f.as_bytes());
            self.radio.push(f);
        }
        self.gcs
            .extend(std::iter::from_fn(|| self.router.poll_gcs_transmit()));
        self.to_fc
            .extend(std::iter::from_fn(|| self.bridge.poll_fc_transmit(now)));
    }

    fn run(&mut self, ticks: u64) {
        for t in 0..ticks {
            self.tick(Instant::from_millis(t * 100));
        }
        // A reader holds a frame of an unknown id while a byte inside it (a sequence number
        // of 0xFD, say) could start a known frame: the next frame's bytes release it.
        let end = Instant::from_millis(ticks * 100);
        let hb = self
            .fc
            .frame(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
        self.bridge.handle_fc_bytes(end, hb.as_bytes());
        self.pump(end);
        self.pump(end + Duration::from_millis(100));
    }

    fn at_gcs(&self, id: u32) -> usize {
        self.gcs.iter().filter(|f| f.message_id() == id).count()
    }
}

/// Regression: with `--key`, a MAVLink 1 autopilot's telemetry was dropped entirely (MAVLink 1
/// cannot be signed) while the bridge's status line counted it as sent on the radio.
#[test]
fn mavlink1_autopilot_telemetry_crosses_a_signed_radio() {
    let mut p = Pair::new(true);
    p.run(100);
    assert_eq!(
        p.at_gcs(ids::ATTITUDE),
        100,
        "every ATTITUDE reached the ground"
    );
    // ArduPilot's own messages too (the scheduler may replace a queued sample by a newer
    // one of the same message: nothing else is missing)
    let replaced = p.bridge.stats().scheduler.replaced as usize;
    assert!(replaced <= 2, "{replaced}");
    assert_eq!(p.at_gcs(SIMSTATE) + replaced, 100);
    assert!(p.at_gcs(ids::HEARTBEAT) >= 100);
    // what the ground gets checks with the messages' own CRC_EXTRA and decodes unchanged
    for f in p.gcs.iter().filter(|f| f.message_id() == SIMSTATE) {
        assert!(f.crc_matches(SIMSTATE_EXTRA));
        assert_eq!(f.payload(), &[0x11; 44]);
    }
    let att = p
        .gcs
        .iter()
        .find(|f| f.message_id() == ids::ATTITUDE)
        .unwrap();
    let MavMessage::ATTITUDE(a) = att.decode::<MavMessage>().unwrap() else {
        panic!("not ATTITUDE")
    };
    assert_eq!(a.roll, 0.25);
    // every radio frame is MAVLink 2 and signed; none was refused
    assert!(
        p.radio
            .iter()
            .all(|f| f.version() == MavlinkVersion::V2 && f.is_signed())
    );
    let (b, r) = (p.bridge.stats(), p.router.stats());
    assert_eq!(b.signing.unsignable, 0);
    // what the status line counts as sent is what the router accepted
    assert_eq!(b.scheduler.sent_frames, r.signing.accepted);
    assert_eq!(b.signing.signed, b.scheduler.sent_frames);
}

/// Regression: the router's LINK_QUALITY read ~97 % loss on a loss-free link with a MAVLink 1
/// autopilot: frames of ids outside our dialect kept the autopilot's sequence numbers among
/// renumbered ones. Unsigned and signed links alike must read no loss.
#[test]
fn mavlink1_autopilot_on_a_loss_free_radio_reads_no_loss() {
    for signed in [false, true] {
        let mut p = Pair::new(signed);
        p.run(100);
        let r = p.router.stats();
        assert_eq!(r.radio_reader.lost, 0, "signed: {signed}");
        assert!(r.radio_reader.frames() >= 300);
        // re-reading the radio bytes independently: MAVLink 2 only, gap-free per sender
        let mut reader = FrameReader::new();
        for f in p.radio.iter().filter(|f| f.system_id() == 1) {
            assert_eq!(f.version(), MavlinkVersion::V2);
            reader.push(f.as_bytes());
        }
        while reader.next_frame().is_some() {}
        assert_eq!(reader.stats().lost, 0);
        if !signed {
            assert_eq!(
                p.bridge.stats().signing.sent_unsigned,
                p.bridge.stats().scheduler.sent_frames
            );
        }
    }
}

/// The ground's frames reach a MAVLink 1 autopilot as MAVLink 1; a ground station that
/// speaks MAVLink 1 gets frames MAVLink 1 can carry (its endpoint converts them).
#[test]
fn mavlink1_peers_get_mavlink1_back() {
    let mut p = Pair::new(true);
    p.run(5);
    let mut gcs = Sender::new(255, 190, MavlinkVersion::V2);
    let cmd = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        target_system: 1,
        target_component: 1,
        command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        param1: 1.0,
        ..Default::default()
    });
    let now = Instant::from_millis(500);
    p.router.handle_gcs_bytes(now, gcs.frame(&cmd).as_bytes());
    p.pump(now);
    p.pump(now + Duration::from_millis(100));
    let at_fc: Vec<&OwnedFrame> = p
        .to_fc
        .iter()
        .filter(|f| f.message_id() == ids::COMMAND_LONG)
        .collect();
    assert_eq!(at_fc.len(), 1);
    assert_eq!(at_fc[0].version(), MavlinkVersion::V1);
    assert_eq!(at_fc[0].decode::<MavMessage>().unwrap(), cmd);
    assert!(p.to_fc.iter().all(|f| f.version() == MavlinkVersion::V1));

    // A MAVLink 1 ground station: the engine keeps making MAVLink 2 (other stations may
    // listen), and every frame of the vehicle's has a MAVLink 1 form with the same message,
    // which the endpoints give that station (`io::ground_version`).
    let mut old_gcs = Sender::new(255, 190, MavlinkVersion::V1);
    let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: MavType::MAV_TYPE_GCS,
        ..Default::default()
    });
    let now = Instant::from_millis(700);
    p.router
        .handle_gcs_bytes(now, old_gcs.frame(&hb).as_bytes());
    p.gcs.clear();
    for t in 8..20 {
        p.tick(Instant::from_millis(t * 100));
    }
    assert!(p.at_gcs(ids::ATTITUDE) >= 10);
    assert!(p.gcs.iter().all(|f| f.version() == MavlinkVersion::V2));
    for f in p.gcs.iter().filter(|f| f.message_id() == ids::ATTITUDE) {
        let v1 = crate::wire::to_v1(f.clone()).expect("ATTITUDE fits MAVLink 1");
        assert_eq!(v1.version(), MavlinkVersion::V1);
        assert_eq!(
            v1.decode::<MavMessage>().unwrap(),
            f.decode::<MavMessage>().unwrap()
        );
    }
}
