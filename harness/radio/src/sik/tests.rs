//! The SiK layer driven on a virtual clock: a radio model between two SiK radios.

use proptest::prelude::*;
use timebase::{Duration, Instant};

use super::frames::{FrameScanner, STX_V1};
use super::status::{self, sik_rssi};
use super::*;
use crate::{Direction, LinkBudget, LinkConfig, Preset, Radio, Silence};

const GUARD: Duration = Duration::from_millis(50);

fn ms(t: u64) -> Instant {
    Instant::ZERO + Duration::from_millis(t)
}

/// Both radios, the model, and what each host has read.
struct World {
    radio: Radio,
    pair: SikPair,
    now: Instant,
    read: [Vec<u8>; 2],
}

impl World {
    fn new(config: LinkConfig) -> World {
        let preset = Preset::sik_64k();
        let radio = Radio::new(&preset, &config, &config).unwrap();
        let side = || Some(SikRadio::new(Board::hm_trp_915(), GUARD, Instant::ZERO));
        World {
            radio,
            pair: SikPair::new(&preset, side(), side()),
            now: Instant::ZERO,
            read: [Vec::new(), Vec::new()],
        }
    }

    fn index(end: End) -> usize {
        match end {
            End::Air => 0,
            End::Ground => 1,
        }
    }

    /// The host on `end` writes `bytes` now.
    fn write(&mut self, end: End, bytes: &[u8]) {
        let air = self
            .pair
            .handle_host_input(self.now, end, bytes, &self.radio);
        self.radio.handle_input(self.now, end.sends(), &air);
        self.drain();
    }

    /// Runs the world to `now + d`.
    fn wait(&mut self, d: Duration) {
        let until = self.now + d;
        loop {
            let next = [self.radio.poll_timeout(), self.pair.poll_timeout()]
                .into_iter()
                .flatten()
                .filter(|&t| t <= until)
                .min();
            let Some(t) = next else { break };
            self.now = t.max(self.now);
            self.radio.handle_timeout(self.now);
            self.pair.handle_timeout(self.now, &self.radio);
            self.drain();
            if t < self.now {
                // Nothing moved time: the engines are done with this instant.
                break;
            }
        }
        self.now = until;
        self.radio.handle_timeout(until);
        self.pair.handle_timeout(until, &self.radio);
        self.drain();
    }

    fn drain(&mut self) {
        for (d, to) in [
            (Direction::Downlink, End::Ground),
            (Direction::Uplink, End::Air),
        ] {
            while let Some(bytes) = self.radio.poll_output(d) {
                self.pair.handle_air_output(to, &bytes);
            }
        }
        if let Some(p) = self.pair.take_presets() {
            self.radio = self.radio.rebuilt(&p[0], &p[1]).unwrap();
        }
        for end in [End::Air, End::Ground] {
            while let Some(out) = self.pair.poll_host_output(end) {
                self.read[Self::index(end)].extend_from_slice(&out);
            }
        }
    }

    fn take(&mut self, end: End) -> String {
        String::from_utf8_lossy(&std::mem::take(&mut self.read[Self::index(end)])).into_owned()
    }

    /// Guard, `+++`, guard: the host on `end` is in command mode.
    fn enter(&mut self, end: End) {
        self.wait(GUARD + Duration::from_millis(1));
        self.write(end, b"+++");
        self.wait(GUARD + Duration::from_millis(1));
        assert!(self.take(end).ends_with("OK\r\n"));
    }

    /// Types `line` + CR on `end` and waits long enough for a remote answer.
    fn command(&mut self, end: End, line: &str) -> String {
        self.write(end, format!("{line}\r").as_bytes());
        self.wait(Duration::from_millis(600));
        self.take(end)
    }
}

#[test]
fn plus_too_soon_after_data_is_data_and_reaches_the_far_host() {
    let mut w = World::new(LinkConfig::default());
    w.wait(Duration::from_millis(100));
    w.write(End::Air, b"data");
    w.wait(Duration::from_millis(GUARD.as_millis() / 2));
    w.write(End::Air, b"+++");
    w.wait(Duration::from_millis(500));
    assert!(!w.pair.radio(End::Air).unwrap().in_command_mode());
    assert_eq!(w.take(End::Air), "");
    assert_eq!(w.take(End::Ground), "data+++");
}

#[test]
fn ati5_round_trips_and_rti5_comes_back_cut_to_one_packet() {
    let mut w = World::new(LinkConfig::default());
    w.enter(End::Ground);
    assert_eq!(
        w.command(End::Ground, "ati"),
        "ATI\r\nSiK 2.2 on HM-TRP\r\n"
    );
    let listing = w.command(End::Ground, "ATI5");
    let body = listing.strip_prefix("ATI5\r\n").unwrap();
    let entries = parse_ati5(body).unwrap();
    let params = w.pair.radio(End::Ground).unwrap().params();
    assert_eq!(entries.len(), 16);
    for (e, p) in entries.iter().zip(Param::ALL) {
        assert_eq!((e.number, e.value), (p.number(), params.get(p)));
    }
    // The remote's listing travels in one captured packet buffer: 252 bytes.
    let remote = w.command(End::Ground, "RTI5");
    let body = remote.strip_prefix("RTI5\r\n").unwrap();
    assert_eq!(body.len(), REMOTE_ANSWER_MAX, "{body:?}");
    assert!(body.starts_with("S0: FORMAT=25\r\n"));
    assert_eq!(w.command(End::Ground, "RTS15?"), "RTS15?\r\n131\r\n");
}

#[test]
fn a_set_takes_effect_only_after_write_and_reboot() {
    let mut w = World::new(LinkConfig::default());
    w.enter(End::Air);
    assert_eq!(w.command(End::Air, "ATS3=7"), "ATS3=7\r\nOK\r\n");
    assert_eq!(w.command(End::Air, "ATS3?"), "ATS3?\r\n7\r\n");
    assert!(w.pair.paired(), "NETID runs from boot: still paired");
    // A reboot without AT&W loses the set.
    w.command(End::Air, "ATZ");
    assert_eq!(w.pair.radio(End::Air).unwrap().settings().net_id, 25);
    w.enter(End::Air);
    assert_eq!(w.command(End::Air, "ATS3?"), "ATS3?\r\n25\r\n");
    w.command(End::Air, "ATS3=7");
    assert_eq!(w.command(End::Air, "AT&W"), "AT&W\r\nOK\r\n");
    assert!(w.pair.paired(), "saved, not booted");
    w.command(End::Air, "ATZ");
    assert_eq!(w.pair.radio(End::Air).unwrap().settings().net_id, 7);
    assert!(!w.pair.paired());
    assert!(
        !w.pair.radio(End::Air).unwrap().in_command_mode(),
        "ATZ leaves command mode"
    );
}

#[test]
fn netid_mismatch_drops_everything_and_remote_commands_go_unanswered() {
    let mut w = World::new(LinkConfig::default());
    w.enter(End::Ground);
    w.command(End::Ground, "ATS3=99");
    w.command(End::Ground, "AT&W");
    w.command(End::Ground, "ATZ");
    w.wait(Duration::from_millis(100));
    // The escape itself was data and went over the air before the reboot.
    assert_eq!(w.take(End::Air), "+++");
    w.write(End::Air, &[0x55; 300]);
    w.write(End::Ground, &[0x66; 300]);
    w.wait(Duration::from_secs(2));
    assert_eq!(
        (w.take(End::Air), w.take(End::Ground)),
        (String::new(), String::new())
    );
    assert_eq!(w.pair.dropped(End::Ground), 300);
    assert!(w.radio.link(Direction::Downlink).stats().bytes_delivered > 0);
    w.enter(End::Ground);
    assert_eq!(w.command(End::Ground, "RTI"), "RTI\r\n", "no answer");
}

#[test]
fn air_speed_and_ecc_reach_the_model_after_reboot() {
    let mut w = World::new(LinkConfig::default());
    for end in [End::Air, End::Ground] {
        w.enter(end);
        w.command(end, "ATS5=1");
        w.command(end, "ATS4=11");
        w.command(end, "AT&W");
        w.command(end, "ATZ");
    }
    assert!(w.pair.paired());
    let up = w.radio.link(Direction::Uplink).preset();
    assert_eq!(up.name, "sik-64k-ecc");
    assert_eq!(up.tx_power_dbm, 11.0);
}

#[test]
fn remote_commands_need_the_link_up() {
    let mut w = World::new(LinkConfig::default());
    w.enter(End::Ground);
    assert_eq!(
        w.command(End::Ground, "RTI"),
        "RTI\r\nSiK 2.2 on HM-TRP\r\n"
    );
    let silence = Silence {
        at_s: w.now.as_secs_f64(),
        for_s: 10.0,
        every_s: None,
    };
    for d in [Direction::Uplink, Direction::Downlink] {
        w.radio.link_mut(d).add_silence(silence).unwrap();
    }
    assert_eq!(w.command(End::Ground, "RTI"), "RTI\r\n");
}

/// A MAVLink 1 frame: id `id`, `len` payload bytes of `fill`, no valid CRC (SiK checks none).
fn frame(id: u8, len: u8, fill: u8) -> Vec<u8> {
    let mut f = vec![STX_V1, len, 0, 1, 1, id];
    f.extend(std::iter::repeat_n(fill, usize::from(len) + 2));
    f
}

#[test]
fn radio_status_goes_between_frames_and_carries_the_reading() {
    let config = LinkConfig {
        budget: LinkBudget::attenuation(70.0),
        ..LinkConfig::default()
    };
    let mut w = World::new(config);
    w.wait(Duration::from_millis(10));
    // The ground sends a long frame; its first half reaches the air host...
    let big = frame(30, 200, 0xAA);
    w.write(End::Ground, &big[..100]);
    w.wait(Duration::from_millis(400));
    assert_eq!(w.read[0].len(), 100, "first half through");
    // ...then the air host's autopilot sends a HEARTBEAT: a report is due, held for the frame.
    w.write(End::Air, &frame(0, 9, 0));
    assert_eq!(w.read[0].len(), 100, "held while a frame is open");
    w.write(End::Ground, &big[100..]);
    w.wait(Duration::from_millis(400));
    let read = std::mem::take(&mut w.read[0]);
    assert_eq!(&read[..big.len()], &big[..], "the frame whole");
    let report = &read[big.len()..];
    assert_eq!(report.len(), 17);
    assert_eq!(&report[..6], &[0xFE, 9, 0, b'3', b'D', 109]);
    let inbound = w.radio.link(Direction::Uplink).receiver();
    // Payload order on the wire: rxerrors, fixed, rssi, remrssi, txbuf, noise, remnoise.
    assert_eq!(report[6 + 4], sik_rssi(inbound.rssi_dbm));
    assert_eq!(report[6 + 4], sik_rssi(-50.0));
    assert_eq!(report[6 + 6], 100, "txbuf: an empty buffer");
    assert_eq!(report[6 + 7], sik_rssi(inbound.noise_dbm));
    // With MAVLINK=0 the next heartbeat arms nothing.
    w.enter(End::Air);
    w.command(End::Air, "ATS6=0");
    w.command(End::Air, "ATO");
    w.write(End::Air, &frame(0, 9, 0));
    w.wait(Duration::from_millis(300));
    assert_eq!(w.take(End::Air), "");
}

#[test]
fn the_report_encoder_agrees_with_the_scanner() {
    let inputs = status::StatusInputs {
        local: crate::ReceiverReading {
            rssi_dbm: -60.0,
            noise_dbm: -100.0,
        },
        remote: crate::ReceiverReading {
            rssi_dbm: -61.0,
            noise_dbm: -101.0,
        },
        tx_free_share: 0.5,
    };
    let bytes = status::encode(&status::radio_status(&inputs), 3);
    let mut s = FrameScanner::default();
    let ends: Vec<_> = bytes.iter().filter_map(|&b| s.push(b)).collect();
    assert_eq!(ends.len(), 1);
    assert!(s.between_frames());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Whatever the host sends, whenever, the radio neither panics nor wedges: a `\r`,
    /// `ATO`, and a guarded `+++` always bring back `OK`, and `ATI` answers.
    #[test]
    fn arbitrary_input_never_panics_and_the_escape_resynchronises(
        chunks in proptest::collection::vec(
            (0u64..120, proptest::collection::vec(
                prop_oneof![Just(b'+'), Just(b'\r'), Just(b'A'), Just(b'T'), any::<u8>()], 0..40)),
            0..40),
    ) {
        let mut r = SikRadio::new(Board::hm_trp_915(), GUARD, Instant::ZERO);
        let mut t = 0;
        let mut air = Vec::new();
        for (gap, bytes) in &chunks {
            t += gap;
            r.handle_timeout(ms(t));
            r.handle_host_input(ms(t), bytes, &mut air);
            r.handle_air_data(bytes);
            r.take_host_output();
            while r.poll_remote_command().is_some() {}
        }
        t += 1;
        r.handle_host_input(ms(t), b"\rATO\r", &mut air);
        t += GUARD.as_millis() + 1;
        r.handle_timeout(ms(t));
        r.handle_host_input(ms(t), b"+++", &mut air);
        r.take_host_output();
        t += GUARD.as_millis() + 1;
        r.handle_timeout(ms(t));
        prop_assert!(r.in_command_mode());
        prop_assert!(String::from_utf8_lossy(&r.take_host_output()).ends_with("OK\r\n"));
        r.handle_host_input(ms(t), b"ATI\r", &mut air);
        prop_assert_eq!(
            String::from_utf8_lossy(&r.take_host_output()).into_owned(),
            "ATI\r\nSiK 2.2 on HM-TRP\r\n"
        );
    }
}
