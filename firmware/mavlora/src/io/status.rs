//! The binaries' status: one value per tick, [`Status`], logged as the `status` line and
//! written as a JSON status line (`--status-json`, [`hostio::status`], fields in
//! `firmware/hostio/STATUS-JSON.md`) from the same value, so the two never disagree. The radio
//! link's part, the same in both binaries, is [`RadioCounters`] and [`RadioGauges`].

use std::path::Path;

use serde::Serialize;

use hostio::status::{StatusError, StatusWriter};

use super::{QueueStats, SerialCounters};
use crate::schedule::SchedulerStats;
use crate::signing::SigningStats;
use crate::wire::ReaderStats;

/// One status of either binary: radio signing, the peer's loss, and the counters and gauges,
/// the radio link's ([`RadioCounters`], [`RadioGauges`]) followed by the program's own (`C`,
/// `G`).
#[derive(Debug, Clone, Serialize)]
pub struct Status<C, G> {
    /// `on`, or `OFF` with `--unsigned`.
    pub signing: &'static str,
    /// The loss the far end last reported on the link towards it (0..=1), `None` before its
    /// first report.
    pub peer_loss: Option<f64>,
    /// Totals and maxima since start: none ever decreases.
    pub counters: Joined<RadioCounters, C>,
    /// Levels now.
    pub gauges: Joined<RadioGauges, G>,
}

/// The radio link's fields and then the program's, in one flat object.
#[derive(Debug, Clone, Serialize)]
pub struct Joined<R, T> {
    /// The radio link's.
    #[serde(flatten)]
    pub radio: R,
    /// The program's own.
    #[serde(flatten)]
    pub program: T,
}

/// What both ends count on their radio link and main loop.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RadioCounters {
    /// Frames read from the radio.
    pub radio_rx: u64,
    /// Frames the sequence numbers say the radio lost.
    pub radio_lost: u64,
    /// Frames from the radio with a bad checksum.
    pub radio_bad_crc: u64,
    /// Frames the radio budget let out.
    pub radio_tx: u64,
    /// Bytes the radio budget let out.
    pub radio_tx_bytes: u64,
    /// Commands and acks the radio budget's full queue dropped (a flood of them, oldest of
    /// the origin with most waiting first).
    pub radio_queue_dropped_commands: u64,
    /// Mission, parameter-request and file-transfer frames its full queue dropped.
    pub radio_queue_dropped_transfers: u64,
    /// Status texts its full queue dropped (the least severe first).
    pub radio_queue_dropped_status: u64,
    /// Telemetry samples its full queue dropped (unnamed ones first).
    pub radio_queue_dropped_telemetry: u64,
    /// Parameter values its full queue dropped.
    pub radio_queue_dropped_params: u64,
    /// Bytes handed to the radio port.
    pub radio_offered_bytes: u64,
    /// Bytes the radio port accepted.
    pub radio_written_bytes: u64,
    /// Bytes never written to the radio (queue full, port closed, a failed write).
    pub radio_dropped_bytes: u64,
    /// Radio write stalls and failures.
    pub radio_write_failures: u64,
    /// Partial frames from the radio dropped after an idle gap.
    pub radio_partials_dropped: u64,
    /// Times the radio port was (re)opened.
    pub radio_opens: u64,
    /// Radio reopens refused because the name led to another device.
    pub radio_refused_opens: u64,
    /// Radio frames dropped for want of a signature.
    pub rejected_unsigned: u64,
    /// Radio frames dropped for a wrong signature.
    pub rejected_bad_signature: u64,
    /// Radio frames dropped as our own, sent back (signed with this end's link id).
    pub rejected_reflected: u64,
    /// Radio frames dropped as replays.
    pub rejected_replayed: u64,
    /// Radio frames dropped as too old.
    pub rejected_stale: u64,
    /// Radio frames dropped as stamped more than a minute ahead of this clock.
    pub rejected_ahead: u64,
    /// Radio frames dropped because the peer has not yet proven it is live (a fresh signing
    /// state waiting for the answer to its challenge).
    pub rejected_unproven: u64,
    /// Frames sent on the radio without a signature (all of them with `--unsigned`).
    pub radio_tx_unsigned: u64,
    /// Events the main loop's inbox dropped when full.
    pub inbox_dropped: u64,
    /// Of those, ground commands and mission traffic.
    pub inbox_dropped_priority: u64,
    /// Most bytes the inbox held at once, counted as memory: events' slots and allocations
    /// (a maximum).
    pub inbox_peak_bytes: u64,
}

/// The radio link's levels.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RadioGauges {
    /// Bytes waiting in the radio port's write queue.
    pub radio_queued_bytes: u64,
}

/// What an engine counts on its radio leg.
#[derive(Debug, Clone, Default)]
pub struct RadioStats {
    /// The radio's frame reader.
    pub reader: ReaderStats,
    /// The radio budget.
    pub scheduler: SchedulerStats,
    /// Radio signing.
    pub signing: SigningStats,
}

impl RadioCounters {
    /// From the engine's radio leg, the radio port and the inbox.
    pub fn new(engine: &RadioStats, port: &SerialCounters, inbox: &QueueStats) -> Self {
        let (r, sent, signing) = (&engine.reader, &engine.scheduler, &engine.signing);
        Self {
            radio_rx: r.frames(),
            radio_lost: r.lost,
            radio_bad_crc: r.bad_crc,
            radio_tx: sent.sent_frames,
            radio_tx_bytes: sent.sent_bytes,
            radio_queue_dropped_commands: sent.dropped_command,
            radio_queue_dropped_transfers: sent.dropped_protocol,
            radio_queue_dropped_status: sent.dropped_status,
            radio_queue_dropped_telemetry: sent.dropped_periodic + sent.dropped_unlisted,
            radio_queue_dropped_params: sent.dropped_param,
            radio_offered_bytes: port.offered_bytes,
            radio_written_bytes: port.written_bytes,
            radio_dropped_bytes: port.dropped_bytes,
            radio_write_failures: port.write_failures,
            radio_partials_dropped: r.partials_dropped,
            radio_opens: port.opens,
            radio_refused_opens: port.refused_opens,
            rejected_unsigned: signing.unsigned,
            rejected_bad_signature: signing.bad_signature,
            rejected_reflected: signing.reflected,
            rejected_replayed: signing.replayed,
            rejected_stale: signing.stale,
            rejected_ahead: signing.ahead,
            rejected_unproven: signing.unproven,
            radio_tx_unsigned: signing.sent_unsigned,
            inbox_dropped: inbox.dropped_items,
            inbox_dropped_priority: inbox.dropped_priority,
            inbox_peak_bytes: inbox.peak_bytes as u64,
        }
    }
}

impl RadioGauges {
    /// From the radio port.
    pub fn new(port: &SerialCounters) -> Self {
        Self {
            radio_queued_bytes: port.queued_bytes,
        }
    }
}

/// Where a binary's status goes: the log's `status` lines always, and the JSON status file
/// when `--status-json` names one. A JSON line that cannot be written is logged (once until
/// writes work again) and never stops the program.
#[derive(Debug)]
pub struct StatusReport {
    json: Option<StatusWriter>,
    stopped: bool,
}

impl StatusReport {
    /// Status for `program`, in the JSON file at `path` too if given (created or truncated
    /// now: a path that cannot be created is an error naming it).
    pub fn open(program: &'static str, path: Option<&Path>) -> Result<Self, StatusError> {
        Ok(Self {
            json: path.map(|p| StatusWriter::create(p, program)).transpose()?,
            stopped: false,
        })
    }

    /// The start line: this crate's version, the process id and `options`.
    pub fn start(&mut self, options: &impl Serialize) -> Result<(), StatusError> {
        match &mut self.json {
            Some(w) => w.start(env!("CARGO_PKG_VERSION"), options),
            None => Ok(()),
        }
    }

    /// A periodic status: the log line and a JSON status line.
    pub fn status(&mut self, status: &impl Serialize) {
        log(status);
        if let Some(w) = &mut self.json {
            w.write_periodic(hostio::status::Kind::Status, status);
        }
    }

    /// An event line in the JSON file (and a log line): `event` names it, `fields` say the rest.
    pub fn event(&mut self, event: &str, fields: &impl Serialize) {
        match hostio::status::fields(fields) {
            Ok(f) => tracing::info!("event {event} {f}"),
            Err(e) => tracing::error!(error = %e, "event not rendered"),
        }
        if let Some(w) = &mut self.json {
            w.event(event, fields);
        }
    }

    /// The stop line (once): how the program ends and, if it got running, its final status
    /// (also logged as a last status line).
    pub fn stop<S: Serialize>(&mut self, status: Option<&S>, result: &anyhow::Result<()>) {
        if std::mem::replace(&mut self.stopped, true) {
            return;
        }
        if let Some(s) = status {
            log(s);
        }
        if let Some(w) = &mut self.json {
            w.stop(super::exit_code(result), result, status);
        }
    }
}

/// The `status` log line: the same fields, by the same names, as the JSON line.
fn log(status: &impl Serialize) {
    match hostio::status::fields(status) {
        Ok(fields) => tracing::info!("status {fields}"),
        Err(e) => tracing::error!(error = %e, "status not rendered"),
    }
}
