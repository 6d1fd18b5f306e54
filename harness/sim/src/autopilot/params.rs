//! Parameters as a simulated autopilot holds and serves them: a table of real lists (dumped
//! from the SITL builds the rig flies, `data/`), and the parameter protocol as ArduPilot and
//! PX4 speak it on their serial port: `PARAM_REQUEST_LIST` streams the whole list at the
//! autopilot's own pace, `PARAM_REQUEST_READ` answers one (by index or by name), `PARAM_SET`
//! stores the value and echoes it (ArduPilot with index 65535, PX4 with the parameter's).
//!
//! Values are kept as the four payload bytes the autopilot sends (ArduPilot's integers cast
//! to float, PX4's byte-wise), and frames are built from them byte for byte, so a test can
//! check that the ground got exactly what the autopilot sent.

use mavlink::MavlinkVersion;
use mavlora::dialect::{MavMessage, PARAM_SET_DATA};
use mavlora::wire::{OwnedFrame, known};
use mavlora::{Duration, Instant};

/// One parameter: its name (16 bytes, zero-padded), type (`MAV_PARAM_TYPE`) and value (the
/// four payload bytes, as the autopilot sends them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParamEntry {
    /// `param_id`.
    pub name: [u8; 16],
    /// `param_type`.
    pub param_type: u8,
    /// The value's payload bytes (little endian).
    pub value: [u8; 4],
}

impl ParamEntry {
    /// The name without its zero padding.
    pub fn name_str(&self) -> &str {
        let len = self.name.iter().position(|&b| b == 0).unwrap_or(16);
        std::str::from_utf8(&self.name[..len]).unwrap_or("")
    }
}

/// ArduCopter 4.6.3 SITL's list as its SERIAL1 sends it (`data/dump_params.py`).
const ARDUCOPTER: &str = include_str!("../../data/ardupilot-copter-4.6.3.tsv");
/// PX4 1.16.0 SITL's (SIH quad) list as its serial MAVLink instance sends it.
const PX4: &str = include_str!("../../data/px4-1.16.0-sih.tsv");

/// A whole parameter list, in index order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParamTable {
    entries: Vec<ParamEntry>,
}

impl ParamTable {
    /// ArduCopter 4.6.3's 1,396 parameters (SITL, `copter.parm` defaults).
    pub fn arducopter() -> Self {
        Self::parse(ARDUCOPTER)
    }

    /// PX4 1.16.0's 904 parameters (SITL, SIH quad): integers byte-wise.
    pub fn px4() -> Self {
        Self::parse(PX4)
    }

    /// `n` made-up parameters `SIM_PARAM_0000`..., REAL32, parameter `i` = `i / 2`.
    pub fn synthetic(n: u16) -> Self {
        let entries = (0..n)
            .map(|i| {
                let mut name = [0u8; 16];
                let text = format!("SIM_PARAM_{i:04}");
                name[..text.len()].copy_from_slice(text.as_bytes());
                ParamEntry {
                    name,
                    param_type: 9,
                    value: (f32::from(i) * 0.5).to_le_bytes(),
                }
            })
            .collect();
        Self { entries }
    }

    /// A table from `data/`'s format: `index<TAB>name<TAB>type<TAB>value hex`, `#` comments.
    pub fn parse(text: &str) -> Self {
        let mut entries = Vec::new();
        for line in text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.is_empty())
        {
            let f: Vec<&str> = line.split('\t').collect();
            assert_eq!(f.len(), 4, "parameter table line {line:?}");
            assert_eq!(f[0].parse::<usize>().ok(), Some(entries.len()), "{line:?}");
            let mut name = [0u8; 16];
            name[..f[1].len()].copy_from_slice(f[1].as_bytes());
            let hex = |k: usize| u8::from_str_radix(&f[3][2 * k..2 * k + 2], 16).unwrap();
            entries.push(ParamEntry {
                name,
                param_type: f[2].parse().unwrap(),
                value: [hex(0), hex(1), hex(2), hex(3)],
            });
        }
        Self { entries }
    }

    /// Parameters.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Parameter `index`.
    pub fn get(&self, index: usize) -> Option<&ParamEntry> {
        self.entries.get(index)
    }

    /// Every parameter, in index order.
    pub fn entries(&self) -> &[ParamEntry] {
        &self.entries
    }

    /// The index of the parameter called `name`.
    pub fn find(&self, name: &[u8; 16]) -> Option<usize> {
        self.entries.iter().position(|e| &e.name == name)
    }

    /// The `PARAM_VALUE` payload of parameter `index` (its `param_index` field `at`).
    pub fn payload(&self, index: usize, at: u16) -> [u8; 25] {
        let e = &self.entries[index];
        let mut p = [0u8; 25];
        p[..4].copy_from_slice(&e.value);
        p[4..6].copy_from_slice(&(self.entries.len() as u16).to_le_bytes());
        p[6..8].copy_from_slice(&at.to_le_bytes());
        p[8..24].copy_from_slice(&e.name);
        p[24] = e.param_type;
        p
    }
}

/// How an autopilot echoes a `PARAM_SET`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SetEcho {
    /// ArduPilot: `param_index` 65535.
    NoIndex,
    /// PX4: the parameter's index.
    Index,
}

/// The parameter protocol of one autopilot (system, component), over its serial frames.
#[derive(Debug, Clone)]
pub struct ParamServer {
    table: ParamTable,
    /// `PARAM_VALUE`s per second while a list streams.
    rate: f64,
    echo: SetEcho,
    /// Next index of a list being streamed, and when.
    streaming: Option<(usize, Instant)>,
    /// Values sent, for the stats.
    sent: u64,
}

impl ParamServer {
    /// `table` served at `rate` values a second, echoing sets as `echo` says.
    pub fn new(table: ParamTable, rate: f64, echo: SetEcho) -> Self {
        Self {
            table,
            rate,
            echo,
            streaming: None,
            sent: 0,
        }
    }

    /// The list it holds now.
    pub fn table(&self) -> &ParamTable {
        &self.table
    }

    /// `PARAM_VALUE`s sent so far.
    pub fn sent(&self) -> u64 {
        self.sent
    }

    /// Whether a list is being streamed.
    pub fn streaming(&self) -> bool {
        self.streaming.is_some()
    }

    /// Starts streaming the whole list at `now` (as on `PARAM_REQUEST_LIST`, or at boot).
    pub fn start_list(&mut self, now: Instant) {
        if !self.table.is_empty() {
            self.streaming = Some((0, now));
        }
    }

    /// Handles a message addressed to the autopilot `system`; the frames it answers with,
    /// built by `frame` from a payload.
    pub fn handle(
        &mut self,
        now: Instant,
        system: u8,
        msg: &MavMessage,
        mut frame: impl FnMut(&[u8; 25]) -> OwnedFrame,
    ) -> Vec<OwnedFrame> {
        match msg {
            MavMessage::PARAM_REQUEST_LIST(r) if r.target_system == system => {
                self.start_list(now);
                Vec::new()
            }
            MavMessage::PARAM_REQUEST_READ(r) if r.target_system == system => {
                let index = match usize::try_from(r.param_index) {
                    Ok(i) => Some(i),
                    // -1: by name
                    Err(_) => self.table.find(&r.param_id.into()),
                };
                match index.filter(|&i| i < self.table.len()) {
                    Some(i) => {
                        self.sent += 1;
                        vec![frame(&self.table.payload(i, i as u16))]
                    }
                    None => Vec::new(),
                }
            }
            MavMessage::PARAM_SET(s) if s.target_system == system => self
                .set(s)
                .map(|i| {
                    let at = match self.echo {
                        SetEcho::NoIndex => u16::MAX,
                        SetEcho::Index => i as u16,
                    };
                    self.sent += 1;
                    vec![frame(&self.table.payload(i, at))]
                })
                .unwrap_or_default(),
            _ => Vec::new(),
        }
    }

    /// Stores a set: the value's bytes as the ground sent them (the ground encodes PX4's
    /// integers byte-wise itself), the type the list says.
    fn set(&mut self, s: &PARAM_SET_DATA) -> Option<usize> {
        let i = self.table.find(&s.param_id.into())?;
        self.table.entries[i].value = s.param_value.to_le_bytes();
        Some(i)
    }

    /// Parameter `index` changed by itself (a calibration at boot): the autopilot tells every
    /// link with index 65535, as ArduPilot does, unasked.
    pub fn notify(
        &mut self,
        index: usize,
        frame: impl FnOnce(&[u8; 25]) -> OwnedFrame,
    ) -> Option<OwnedFrame> {
        (index < self.table.len()).then(|| {
            self.sent += 1;
            frame(&self.table.payload(index, u16::MAX))
        })
    }

    /// The list's values due at `now`, as frames built by `frame`.
    pub fn handle_timeout(
        &mut self,
        now: Instant,
        mut frame: impl FnMut(&[u8; 25]) -> OwnedFrame,
    ) -> Vec<OwnedFrame> {
        let mut out = Vec::new();
        while let Some((index, due)) = self.streaming
            && now >= due
        {
            self.sent += 1;
            out.push(frame(&self.table.payload(index, index as u16)));
            let next = index + 1;
            self.streaming = (next < self.table.len())
                .then(|| (next, due + Duration::from_secs_f64(1.0 / self.rate)));
        }
        out
    }

    /// When the list's next value is due.
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.streaming.map(|(_, due)| due)
    }
}

/// A `PARAM_VALUE` frame from (`system`, `component`) holding `payload` byte for byte, in
/// `version` (MAVLink 2 trims trailing zeros), built without a float: any type byte and any
/// value bits go as they are.
pub fn param_value_frame(
    version: MavlinkVersion,
    system: u8,
    component: u8,
    sequence: u8,
    payload: &[u8; 25],
) -> OwnedFrame {
    let mut bytes = match version {
        MavlinkVersion::V1 => {
            let mut b = vec![0xFE, 25, sequence, system, component, 22];
            b.extend_from_slice(payload);
            b
        }
        MavlinkVersion::V2 => {
            let len = payload.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1);
            let mut b = vec![0xFD, len as u8, 0, 0, sequence, system, component, 22, 0, 0];
            b.extend_from_slice(&payload[..len]);
            b
        }
    };
    let extra = known::crc_extra(22).expect("PARAM_VALUE is known");
    let crc = mavlink::calculate_crc(&bytes[1..], extra);
    bytes.extend_from_slice(&crc.to_le_bytes());
    OwnedFrame::new_checked(bytes).expect("well-formed frame")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_real_lists_load_whole() {
        let ap = ParamTable::arducopter();
        assert_eq!(ap.len(), 1396);
        assert_eq!(ap.get(8).unwrap().name_str(), "RTL_ALT");
        // ArduPilot casts integers to float: RTL_ALT (INT32) 1500 is 1500.0
        assert_eq!(ap.get(8).unwrap().value, 1500.0f32.to_le_bytes());
        let px4 = ParamTable::px4();
        assert_eq!(px4.len(), 904);
        // PX4 sends integers byte-wise: BAT1_N_CELLS (INT32) 4 is 04 00 00 00
        let cells = px4.find(&px4.get(3).unwrap().name).unwrap();
        assert_eq!(px4.get(cells).unwrap().value, [4, 0, 0, 0]);
        assert_eq!(px4.get(cells).unwrap().param_type, 6);
    }
}
