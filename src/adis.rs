//! ADIS-over-CAN input: part profiles, frame decoding and sample assembly.
//!
//! Pure code: no sockets, no files, no clocks. Frames come in as
//! `(time, id, data)` from wherever they were read (a live socket, a candump
//! log, a test); complete, checksum-verified samples come out.
//!
//! The contract is `shared/protocol/adis-can.md`: one sample = four classic
//! CAN frames (GYRO, ACCEL, MAGN, AUX) carrying the same `DATA_CNT`, every
//! 16-bit field little-endian, `CHECKSUM` = sum of the 30 bytes before it.

use serde::{Deserialize, Serialize};

/// Which of the four frames of a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    Gyro = 0,
    Accel = 1,
    Magn = 2,
    Aux = 3,
}

/// CAN identifiers of the four input frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputIds {
    pub gyro: u32,
    pub accel: u32,
    pub magn: u32,
    pub aux: u32,
}

impl InputIds {
    pub const DEFAULT: InputIds = InputIds { gyro: 0x100, accel: 0x101, magn: 0x102, aux: 0x103 };

    pub fn part(&self, id: u32) -> Option<Part> {
        if id == self.gyro {
            Some(Part::Gyro)
        } else if id == self.accel {
            Some(Part::Accel)
        } else if id == self.magn {
            Some(Part::Magn)
        } else if id == self.aux {
            Some(Part::Aux)
        } else {
            None
        }
    }

    pub fn all(&self) -> [u32; 4] {
        [self.gyro, self.accel, self.magn, self.aux]
    }
}

/// Scales of one ADIS part as bridged onto CAN. Data, not code: every field
/// can be overridden in the config file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    pub name: String,
    /// deg/s per LSB.
    pub gyro_lsb: f64,
    /// g per LSB (specific force).
    pub accel_lsb: f64,
    /// gauss per LSB.
    pub magn_lsb: f64,
    /// deg C per LSB.
    pub temp_lsb: f64,
    /// deg C at TEMP_OUT = 0.
    pub temp_offset: f64,
    /// Nominal sample rate, Hz.
    pub rate_hz: f64,
    /// False for parts without a magnetometer: yaw is then not measured.
    pub magnetometer: bool,
    /// 1-sigma of the gyro's turn-on bias assumed at power-on without a
    /// saved bias, deg/s (`[ekf] init_bias_sigma` overrides it).
    pub gyro_bias_sigma: f64,
}

/// Built-in profiles. Values from the parts' data sheets (16-bit output
/// registers as the bridge forwards them).
pub fn builtin_profile(name: &str) -> Option<Profile> {
    let p = |name: &str, g, a, m, tl, to, r, mag, bs| Profile {
        name: name.to_string(),
        gyro_lsb: g,
        accel_lsb: a,
        magn_lsb: m,
        temp_lsb: tl,
        temp_offset: to,
        rate_hz: r,
        magnetometer: mag,
        gyro_bias_sigma: bs,
    };
    // The turn-on bias sigma covers the data sheets' initial bias error with
    // margin: real ADIS16448 units have been measured at 4-5 deg/s on one axis.
    match name {
        // ADIS16448: 0.04 deg/s, 0.833 mg, 142.9 ugauss, 0.07386 C (0 LSB = 31 C), 819.2/4 Hz.
        "adis16448" => Some(p("adis16448", 0.04, 0.833e-3, 142.9e-6, 0.07386, 31.0, 204.8, true, 3.0)),
        // ADIS16405: 0.05 deg/s, 3.33 mg, 0.5 mgauss, 0.14 C (0 LSB = 25 C), 819.2 Hz.
        "adis16405" => Some(p("adis16405", 0.05, 3.33e-3, 0.5e-3, 0.14, 25.0, 819.2, true, 3.0)),
        // ADIS16465-1 (ADIS1646x class, +-125 deg/s): 1/160 deg/s, 0.25 mg, 0.1 C
        // (0 LSB = 25 C), 2000 Hz; no magnetometer (the bridge sends a zero MAGN frame).
        "adis16465-1" => Some(p("adis16465-1", 1.0 / 160.0, 0.25e-3, 0.0, 0.1, 25.0, 2000.0, false, 1.0)),
        _ => None,
    }
}

pub const BUILTIN_PROFILES: [&str; 3] = ["adis16448", "adis16405", "adis16465-1"];

/// One complete, checksum-verified IMU sample in physical units.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Sample {
    /// DATA_CNT of the sample.
    pub cnt: u16,
    /// Time of the frame that completed the sample, microseconds.
    pub t_us: u64,
    /// Sample periods since the previous accepted sample (1 normally, more
    /// after lost samples; 0 for the first sample and after a counter restart,
    /// when the time since the previous sample is unknown).
    pub steps: u32,
    /// Gyro, deg/s, body FRD.
    pub gyro: [f64; 3],
    /// Specific force, g, body FRD.
    pub accel: [f64; 3],
    /// Magnetic field, gauss, body FRD.
    pub magn: [f64; 3],
    /// Temperature, deg C.
    pub temp: f64,
    /// DIAG_STAT register; non-zero marks the sample suspect.
    pub diag: u16,
}

impl Sample {
    pub fn suspect(&self) -> bool {
        self.diag != 0
    }
}

/// Raw register values of one sample (what the bridge puts on the bus).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct RawSample {
    pub gyro: [i16; 3],
    pub accel: [i16; 3],
    pub magn: [i16; 3],
    pub temp: i16,
    pub diag: u16,
    pub cnt: u16,
}

impl RawSample {
    /// The four frames' payloads, in bus order, with the checksum filled in.
    pub fn encode(&self) -> [[u8; 8]; 4] {
        let mut f = [[0u8; 8]; 4];
        let put3 = |d: &mut [u8; 8], v: &[i16; 3], cnt: u16| {
            for (i, x) in v.iter().enumerate() {
                d[2 * i..2 * i + 2].copy_from_slice(&x.to_le_bytes());
            }
            d[6..8].copy_from_slice(&cnt.to_le_bytes());
        };
        put3(&mut f[0], &self.gyro, self.cnt);
        put3(&mut f[1], &self.accel, self.cnt);
        put3(&mut f[2], &self.magn, self.cnt);
        f[3][0..2].copy_from_slice(&self.temp.to_le_bytes());
        f[3][2..4].copy_from_slice(&self.diag.to_le_bytes());
        f[3][4..6].copy_from_slice(&self.cnt.to_le_bytes());
        let sum = checksum(&f);
        f[3][6..8].copy_from_slice(&sum.to_le_bytes());
        f
    }

    /// Quantise a physical sample to register values (round to nearest LSB,
    /// saturating at the i16 range).
    pub fn quantise(p: &Profile, gyro: [f64; 3], accel: [f64; 3], magn: [f64; 3], temp: f64) -> RawSample {
        let q = |v: f64, lsb: f64| -> i16 {
            if lsb <= 0.0 || !v.is_finite() {
                0
            } else {
                (v / lsb).round().clamp(i16::MIN as f64, i16::MAX as f64) as i16
            }
        };
        RawSample {
            gyro: gyro.map(|v| q(v, p.gyro_lsb)),
            accel: accel.map(|v| q(v, p.accel_lsb)),
            magn: magn.map(|v| q(v, p.magn_lsb)),
            temp: q(temp - p.temp_offset, p.temp_lsb),
            diag: 0,
            cnt: 0,
        }
    }
}

/// CHECKSUM of the contract: sum of bytes 0-7 of GYRO, ACCEL, MAGN and bytes
/// 0-5 of AUX, modulo 65536.
pub fn checksum(f: &[[u8; 8]; 4]) -> u16 {
    let mut s: u32 = 0;
    for d in &f[..3] {
        for b in d {
            s += *b as u32;
        }
    }
    for b in &f[3][..6] {
        s += *b as u32;
    }
    (s & 0xFFFF) as u16
}

#[inline]
fn le_i16(d: &[u8], i: usize) -> i16 {
    i16::from_le_bytes([d[i], d[i + 1]])
}
#[inline]
fn le_u16(d: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([d[i], d[i + 1]])
}

/// Consecutive out-of-order frames after which the counter is taken to have restarted.
pub const RESYNC_AFTER: u32 = 8;

/// Why a frame or a sample was dropped. Every drop is counted by cause.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Drop {
    /// A frame whose ID is not one of the four input IDs (or is extended/remote/FD).
    UnknownId,
    /// An input ID with a DLC other than 8.
    WrongDlc,
    /// A frame for a part already received for the sample being assembled,
    /// or for the sample just completed.
    Duplicate,
    /// A frame whose DATA_CNT is older than the last accepted sample.
    OutOfOrder,
    /// A sample abandoned incomplete (a frame of a newer sample arrived first).
    Partial,
    /// A complete sample whose CHECKSUM does not match.
    Checksum,
}

impl Drop {
    pub const ALL: [Drop; 6] = [Drop::UnknownId, Drop::WrongDlc, Drop::Duplicate, Drop::OutOfOrder, Drop::Partial, Drop::Checksum];
    pub fn name(self) -> &'static str {
        match self {
            Drop::UnknownId => "unknown_id",
            Drop::WrongDlc => "wrong_dlc",
            Drop::Duplicate => "duplicate",
            Drop::OutOfOrder => "out_of_order",
            Drop::Partial => "partial",
            Drop::Checksum => "checksum",
        }
    }
}

/// Counters of the input path.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct InputCounters {
    pub frames: u64,
    pub samples: u64,
    pub unknown_id: u64,
    pub wrong_dlc: u64,
    pub duplicate: u64,
    pub out_of_order: u64,
    pub partial: u64,
    pub checksum: u64,
    /// Samples with DIAG_STAT != 0 (accepted, not fused).
    pub suspect: u64,
    /// Counter gaps (events).
    pub gaps: u64,
    /// Samples lost in counter gaps (every counter value never delivered,
    /// including those of dropped samples).
    pub lost: u64,
    /// Counter restarts detected (a run of frames older than the last sample).
    pub resyncs: u64,
}

impl InputCounters {
    pub fn get(&self, d: Drop) -> u64 {
        match d {
            Drop::UnknownId => self.unknown_id,
            Drop::WrongDlc => self.wrong_dlc,
            Drop::Duplicate => self.duplicate,
            Drop::OutOfOrder => self.out_of_order,
            Drop::Partial => self.partial,
            Drop::Checksum => self.checksum,
        }
    }
    pub(crate) fn bump(&mut self, d: Drop) {
        let c = match d {
            Drop::UnknownId => &mut self.unknown_id,
            Drop::WrongDlc => &mut self.wrong_dlc,
            Drop::Duplicate => &mut self.duplicate,
            Drop::OutOfOrder => &mut self.out_of_order,
            Drop::Partial => &mut self.partial,
            Drop::Checksum => &mut self.checksum,
        };
        *c += 1;
    }
    /// All drops, whatever the cause.
    pub fn dropped(&self) -> u64 {
        Drop::ALL.iter().map(|d| self.get(*d)).sum()
    }
    /// Drops that are faults of the IMU stream: all but unknown IDs (on a
    /// shared vehicle bus other IDs are normal traffic, and the daemon's
    /// kernel filter never lets them in).
    pub fn errors(&self) -> u64 {
        self.dropped() - self.unknown_id
    }
}

/// What one pushed frame produced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Push {
    /// Stored; the sample is not complete yet.
    Pending,
    /// The frame completed a valid sample.
    Sample(Sample),
    /// Something was dropped (the frame itself, or the sample it closed or abandoned).
    Dropped(Drop),
}

/// A classic CAN frame as the assembler sees it.
#[derive(Clone, Copy, Debug)]
pub struct RawFrame<'a> {
    pub id: u32,
    pub extended: bool,
    pub remote: bool,
    /// A CAN FD frame (never an input frame: the contract is classic CAN).
    pub fd: bool,
    pub data: &'a [u8],
}

impl<'a> RawFrame<'a> {
    /// A classic standard-ID data frame.
    pub fn classic(id: u32, data: &'a [u8]) -> RawFrame<'a> {
        RawFrame { id, extended: false, remote: false, fd: false, data }
    }

    /// View any `embedded_can::Frame` (a live socketcan frame, a test frame).
    pub fn from_frame<F: embedded_can::Frame>(f: &'a F) -> RawFrame<'a> {
        let (id, extended) = match f.id() {
            embedded_can::Id::Standard(s) => (s.as_raw() as u32, false),
            embedded_can::Id::Extended(e) => (e.as_raw(), true),
        };
        RawFrame { id, extended, remote: f.is_remote_frame(), fd: false, data: f.data() }
    }
}

/// Assembles samples from frames. Holds one sample in progress.
#[derive(Clone, Debug)]
pub struct Assembler {
    ids: InputIds,
    profile: Profile,
    cur_cnt: u16,
    have: u8,
    buf: [[u8; 8]; 4],
    /// DATA_CNT of the last accepted sample.
    last: Option<u16>,
    /// Consecutive frames rejected as older than `last`.
    stale_run: u32,
    pub counters: InputCounters,
}

impl Assembler {
    pub fn new(profile: Profile, ids: InputIds) -> Self {
        Assembler { ids, profile, cur_cnt: 0, have: 0, buf: [[0; 8]; 4], last: None, stale_run: 0, counters: InputCounters::default() }
    }

    pub fn ids(&self) -> &InputIds {
        &self.ids
    }

    fn drop(&mut self, d: Drop) -> Push {
        self.counters.bump(d);
        Push::Dropped(d)
    }

    /// Push one frame received at `t_us`.
    pub fn push(&mut self, t_us: u64, f: RawFrame<'_>) -> Push {
        self.counters.frames += 1;
        let part = match (f.extended || f.remote || f.fd, self.ids.part(f.id)) {
            (false, Some(p)) => p,
            _ => return self.drop(Drop::UnknownId),
        };
        if f.data.len() != 8 {
            return self.drop(Drop::WrongDlc);
        }
        let cnt = if part == Part::Aux { le_u16(f.data, 4) } else { le_u16(f.data, 6) };
        if let Some(last) = self.last {
            // Signed distance from the last accepted sample, modulo 2^16.
            let d = cnt.wrapping_sub(last) as i16;
            if d == 0 {
                return self.drop(Drop::Duplicate);
            }
            if d < 0 {
                self.stale_run += 1;
                if self.stale_run < RESYNC_AFTER {
                    return self.drop(Drop::OutOfOrder);
                }
                // Two samples' worth of frames in a row, all "older" than the
                // last sample: the sensor restarted its counter. Start over
                // rather than waiting for the counter to catch up.
                self.counters.resyncs += 1;
                self.last = None;
                self.have = 0;
            }
        }
        self.stale_run = 0;
        if self.have != 0 && cnt != self.cur_cnt {
            // Another sample (newer than the last accepted one) started before
            // this one completed: abandon this one. The newcomer wins even when
            // its counter is lower, so one frame with a corrupted DATA_CNT
            // costs one sample, not every sample up to the corrupted value.
            self.have = 0;
            self.counters.bump(Drop::Partial);
        }
        let bit = 1u8 << (part as u8);
        if self.have & bit != 0 {
            return self.drop(Drop::Duplicate);
        }
        self.cur_cnt = cnt;
        self.have |= bit;
        self.buf[part as usize].copy_from_slice(f.data);
        if self.have != 0b1111 {
            return Push::Pending;
        }
        self.have = 0;
        let want = le_u16(&self.buf[3], 6);
        if checksum(&self.buf) != want {
            return self.drop(Drop::Checksum);
        }
        let steps = match self.last {
            None => 0,
            Some(last) => cnt.wrapping_sub(last) as u32,
        };
        if steps > 1 {
            self.counters.gaps += 1;
            self.counters.lost += (steps - 1) as u64;
        }
        self.last = Some(cnt);
        self.counters.samples += 1;
        let s = self.decode(t_us, steps);
        if s.suspect() {
            self.counters.suspect += 1;
        }
        Push::Sample(s)
    }

    fn decode(&self, t_us: u64, steps: u32) -> Sample {
        let p = &self.profile;
        let b = &self.buf;
        let v3 = |d: &[u8; 8], lsb: f64| [le_i16(d, 0) as f64 * lsb, le_i16(d, 2) as f64 * lsb, le_i16(d, 4) as f64 * lsb];
        Sample {
            cnt: le_u16(&b[3], 4),
            t_us,
            steps,
            gyro: v3(&b[0], p.gyro_lsb),
            accel: v3(&b[1], p.accel_lsb),
            magn: v3(&b[2], p.magn_lsb),
            temp: le_i16(&b[3], 0) as f64 * p.temp_lsb + p.temp_offset,
            diag: le_u16(&b[3], 2),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prof() -> Profile {
        builtin_profile("adis16448").unwrap()
    }

    fn frames(cnt: u16) -> [[u8; 8]; 4] {
        RawSample { gyro: [25, -10, 3], accel: [0, 1, -1200], magn: [1000, 0, 2000], temp: 14, diag: 0, cnt }.encode()
    }

    fn push_all(a: &mut Assembler, f: &[[u8; 8]; 4]) -> Push {
        let ids = [0x100, 0x101, 0x102, 0x103];
        let mut last = Push::Pending;
        for (i, d) in f.iter().enumerate() {
            last = a.push(0, RawFrame { id: ids[i], extended: false, remote: false, fd: false, data: d });
        }
        last
    }

    #[test]
    fn decodes_contract_example_scales() {
        let mut a = Assembler::new(prof(), InputIds::DEFAULT);
        match push_all(&mut a, &frames(7)) {
            Push::Sample(s) => {
                assert_eq!(s.cnt, 7);
                assert!((s.gyro[0] - 1.0).abs() < 1e-12);
                assert!((s.gyro[1] + 0.4).abs() < 1e-12);
                assert!((s.accel[2] + 0.9996).abs() < 1e-9);
                assert!((s.temp - (31.0 + 14.0 * 0.07386)).abs() < 1e-9);
                assert_eq!(s.steps, 0);
            }
            other => panic!("expected a sample, got {other:?}"),
        }
    }

    #[test]
    fn counts_gaps_duplicates_and_wrap() {
        let mut a = Assembler::new(prof(), InputIds::DEFAULT);
        assert!(matches!(push_all(&mut a, &frames(65534)), Push::Sample(_)));
        assert!(matches!(push_all(&mut a, &frames(65535)), Push::Sample(s) if s.steps == 1));
        // wrap to 0, then skip 1..=3
        assert!(matches!(push_all(&mut a, &frames(0)), Push::Sample(s) if s.steps == 1));
        assert!(matches!(push_all(&mut a, &frames(4)), Push::Sample(s) if s.steps == 4));
        assert_eq!(a.counters.gaps, 1);
        assert_eq!(a.counters.lost, 3);
        // whole sample repeated
        assert_eq!(push_all(&mut a, &frames(4)), Push::Dropped(Drop::Duplicate));
        assert_eq!(a.counters.duplicate, 4);
        // an old sample
        assert_eq!(push_all(&mut a, &frames(2)), Push::Dropped(Drop::OutOfOrder));
        assert_eq!(a.counters.samples, 4);
    }

    #[test]
    fn counter_restart_resyncs() {
        let mut a = Assembler::new(prof(), InputIds::DEFAULT);
        assert!(matches!(push_all(&mut a, &frames(20000)), Push::Sample(_)));
        assert_eq!(push_all(&mut a, &frames(0)), Push::Dropped(Drop::OutOfOrder));
        // the second restarted sample trips the resync on its 4th frame
        assert_eq!(push_all(&mut a, &frames(1)), Push::Pending);
        assert!(matches!(push_all(&mut a, &frames(2)), Push::Sample(s) if s.steps == 0));
        assert_eq!(a.counters.resyncs, 1);
    }

    #[test]
    fn partial_checksum_dlc_unknown() {
        let mut a = Assembler::new(prof(), InputIds::DEFAULT);
        let f = frames(10);
        a.push(0, RawFrame { id: 0x100, extended: false, remote: false, fd: false, data: &f[0] });
        a.push(0, RawFrame { id: 0x101, extended: false, remote: false, fd: false, data: &f[1] });
        // sample 11 starts: 10 is abandoned
        assert!(matches!(push_all(&mut a, &frames(11)), Push::Sample(_)));
        assert_eq!(a.counters.partial, 1);
        let mut bad = frames(12);
        bad[1][0] ^= 0x40;
        assert_eq!(push_all(&mut a, &bad), Push::Dropped(Drop::Checksum));
        assert_eq!(
            a.push(0, RawFrame { id: 0x100, extended: false, remote: false, fd: false, data: &[1, 2, 3, 4, 5] }),
            Push::Dropped(Drop::WrongDlc)
        );
        assert_eq!(
            a.push(0, RawFrame { id: 0x7ff, extended: false, remote: false, fd: false, data: &[0; 8] }),
            Push::Dropped(Drop::UnknownId)
        );
        assert_eq!(
            a.push(0, RawFrame { id: 0x100, extended: true, remote: false, fd: false, data: &[0; 8] }),
            Push::Dropped(Drop::UnknownId)
        );
        assert_eq!(a.counters.dropped(), 5);
    }

    #[test]
    fn suspect_samples_are_delivered_and_counted() {
        let mut a = Assembler::new(prof(), InputIds::DEFAULT);
        let r = RawSample { diag: 0x0040, cnt: 3, ..Default::default() };
        assert!(matches!(push_all(&mut a, &r.encode()), Push::Sample(s) if s.suspect()));
        assert_eq!(a.counters.suspect, 1);
    }
}
