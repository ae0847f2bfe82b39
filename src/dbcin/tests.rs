//! The plan and the assembler on hand-made frames. The frames are built
//! here byte by byte from the DBC's layout as written in the files, not by
//! the plan under test; python `cantools` checks the same decoding
//! independently in `tests/dbc_input.rs`.

use super::*;
use crate::adis::{Drop, Push, RawFrame};
use crate::config::Config;
use std::sync::Arc;

const MM7_DBC: &str = include_str!("../../config/mm7p10.dbc");
const MM7_TOML: &str = include_str!("../../config/mm7p10.toml");

fn plan(toml: &str, dbc: &str) -> Result<DbcPlan, (String, String)> {
    let c = Config::parse(toml, "t.toml").map_err(|e| ("parse".to_string(), e.to_string()))?;
    DbcPlan::build(&c.input, dbc, "t.dbc", 25.0)
}

/// CRC-8 SAE J1850 written out bit by bit, MSB first (check value of "123456789": 0x4B).
fn crc8(d: &[u8]) -> u8 {
    let mut c = 0xFFu8;
    for &b in d {
        for k in (0..8).rev() {
            let top = ((c >> 7) ^ (b >> k)) & 1;
            c <<= 1;
            if top == 1 {
                c ^= 0x1D;
            }
        }
    }
    !c
}

/// One MM7.10 frame as config/mm7p10.dbc lays it out: rate raw in bytes
/// 0-1, temp raw in byte 2, status nibble in byte 3, accel raw in bytes
/// 4-5, counter in the high nibble of byte 6, CRC in byte 7.
fn mm7(rate: u16, temp: u8, stat: u8, acc: u16, cnt: u8) -> [u8; 8] {
    let mut d = [0u8; 8];
    d[0..2].copy_from_slice(&rate.to_le_bytes());
    d[2] = temp;
    d[3] = stat;
    d[4..6].copy_from_slice(&acc.to_le_bytes());
    d[6] = cnt << 4;
    d[7] = crc8(&d[..7]);
    d
}

fn push_sample(a: &mut DbcAssembler, cnt: u8, stat: u8) -> Push {
    let mut last = Push::Pending;
    for (id, rate, acc) in [(0x174, 32768 + 200, 32768 + 100), (0x178, 32768 - 40, 32768 - 7845), (0x17C, 32768 + 2, 32768 + 3)] {
        last = a.push(0, RawFrame::classic(id, &mm7(rate, 75, stat, acc, cnt)));
    }
    last
}

#[test]
fn crc_j1850_check_value() {
    assert_eq!(crc8(b"123456789"), 0x4B);
    let mut d = b"123456789\x4B".to_vec();
    assert!(Crc::J1850 { at: 9 }.ok(&d));
    d[3] ^= 1;
    assert!(!Crc::J1850 { at: 9 }.ok(&d));
}

#[test]
fn mm7_sample_decodes_with_scales_signs_and_temperature() {
    let p = plan(MM7_TOML, MM7_DBC).unwrap();
    assert_eq!(p.assembly, Assembly::Counter { modulus: 16 });
    assert_eq!(p.measured(), 0x7F);
    let mut a = DbcAssembler::new(Arc::new(p));
    let Push::Sample(s) = push_sample(&mut a, 3, 0) else { panic!("no sample") };
    let close = |x: f64, y: f64| (x - y).abs() < 1e-9;
    // gyro_x = RollRate (TX2), gyro_y = -PitchRate (TX3), gyro_z = YawRate (TX1)
    assert!(close(s.gyro[0], -40.0 * 0.005), "{s:?}");
    assert!(close(s.gyro[1], -2.0 * 0.005), "{s:?}");
    assert!(close(s.gyro[2], 200.0 * 0.005), "{s:?}");
    // 32768 * 0.000127465 - 4.1768 = -0.0000... : offsets are the DBC's, not assumed exact
    let acc0 = 32768.0 * 0.000127465 - 4.1768;
    assert!(close(s.accel[0], -7845.0 * 0.000127465 + acc0), "{s:?}");
    assert!(close(s.accel[1], 100.0 * 0.000127465 + acc0), "{s:?}");
    assert!(close(s.accel[2], 3.0 * 0.000127465 + acc0), "{s:?}");
    assert!(close(s.temp, 25.0) && s.magn == [0.0; 3] && s.diag == 0 && s.steps == 0);
}

#[test]
fn mm7_counters_gaps_duplicates_partials_checksums_and_validity() {
    let mut a = DbcAssembler::new(Arc::new(plan(MM7_TOML, MM7_DBC).unwrap()));
    assert!(matches!(push_sample(&mut a, 14, 0), Push::Sample(s) if s.steps == 0));
    assert!(matches!(push_sample(&mut a, 15, 0), Push::Sample(s) if s.steps == 1 && s.cnt == 1));
    // wrap 15 -> 0, then skip 1 and 2
    assert!(matches!(push_sample(&mut a, 0, 0), Push::Sample(s) if s.steps == 1));
    assert!(matches!(push_sample(&mut a, 3, 0), Push::Sample(s) if s.steps == 3 && s.cnt == 5));
    assert_eq!((a.counters.gaps, a.counters.lost), (1, 2));
    // the same sample again: three duplicates
    assert_eq!(push_sample(&mut a, 3, 0), Push::Dropped(Drop::Duplicate));
    assert_eq!(a.counters.duplicate, 3);
    // an older one
    assert_eq!(push_sample(&mut a, 1, 0), Push::Dropped(Drop::OutOfOrder));
    // two frames of 4, then sample 5: 4 is abandoned
    a.push(0, RawFrame::classic(0x174, &mm7(1, 1, 0, 1, 4)));
    a.push(0, RawFrame::classic(0x178, &mm7(1, 1, 0, 1, 4)));
    assert!(matches!(push_sample(&mut a, 5, 0), Push::Sample(s) if s.steps == 2));
    assert_eq!(a.counters.partial, 1);
    // a corrupted byte: the frame fails its CRC
    let mut bad = mm7(1, 1, 0, 1, 6);
    bad[0] ^= 0x10;
    assert_eq!(a.push(0, RawFrame::classic(0x174, &bad)), Push::Dropped(Drop::Checksum));
    assert_eq!(a.push(0, RawFrame::classic(0x174, &bad[..7])), Push::Dropped(Drop::WrongDlc));
    assert_eq!(a.push(0, RawFrame::classic(0x175, &bad)), Push::Dropped(Drop::UnknownId));
    assert_eq!(a.push(0, RawFrame { id: 0x174, extended: true, remote: false, fd: false, data: &bad }), Push::Dropped(Drop::UnknownId));
    // YawRate_STAT (TX1) not 0: delivered, suspect
    assert!(matches!(push_sample(&mut a, 7, 2), Push::Sample(s) if s.suspect() && s.diag == 1));
    assert_eq!(a.counters.suspect, 1);
    // and the next good one is not
    assert!(matches!(push_sample(&mut a, 8, 0), Push::Sample(s) if !s.suspect()));
    assert_eq!(a.counters.samples, 7);
}

const J1939_DBC: &str = include_str!("../../config/j1939-imu.dbc");
const J1939_TOML: &str = include_str!("../../config/j1939-imu.toml");

/// ARI and ACCS frames as config/j1939-imu.dbc lays them out: three
/// little-endian u16 in bytes 0-5, figures of merit in byte 6, latency in byte 7.
fn j1939(v: [u16; 3], fom: u8) -> [u8; 8] {
    let mut d = [0u8; 8];
    for (k, x) in v.iter().enumerate() {
        d[2 * k..2 * k + 2].copy_from_slice(&x.to_le_bytes());
    }
    d[6] = fom;
    d[7] = 4;
    d
}

#[test]
fn j1939_matches_pgn_and_source_address_whatever_the_priority() {
    let p = plan(J1939_TOML, J1939_DBC).unwrap();
    assert!(matches!(p.assembly, Assembly::Window { us: 5000 }));
    let mut a = DbcAssembler::new(Arc::new(p));
    let ext = |id: u32, d: &[u8; 8], a: &mut DbcAssembler, t: u64| {
        let d = *d;
        a.push(t, RawFrame { id, extended: true, remote: false, fd: false, data: &d })
    };
    // 1/128 deg/s offset -250: raw 32000 = 0 deg/s; 0.01 m/s^2 offset -320: raw 32000 = 0
    let ari = j1939([32000 + 128, 32000 - 256, 32000 + 64], 0);
    let accs = j1939([32000 + 100, 32000, 32000 - 981], 0);
    // priority 3 and priority 6 both match; source address 0x81 is another unit
    assert_eq!(ext(0x0CF02A81, &ari, &mut a, 0), Push::Dropped(Drop::UnknownId));
    assert_eq!(ext(0x18F02A80, &ari, &mut a, 1000), Push::Pending);
    let Push::Sample(s) = ext(0x0CF02D80, &accs, &mut a, 3000) else { panic!() };
    // ARI: pitch, roll, yaw in that order (gyro_x = roll, gyro_y = pitch, gyro_z = yaw)
    let close = |x: f64, y: f64| (x - y).abs() < 1e-9;
    assert!(close(s.gyro[0], -2.0) && close(s.gyro[1], 1.0) && close(s.gyro[2], 0.5), "{s:?}");
    // ACCS: lateral, longitudinal, vertical (accel_x = longitudinal, accel_y = lateral)
    assert!(close(s.accel[0], 0.0) && close(s.accel[1], 1.0 / G0) && close(s.accel[2], -9.81 / G0), "{s:?}");
    // window: ARI at 11 ms, ACCS at 17 ms (6 ms later, past the 5 ms window): partial
    assert_eq!(ext(0x0CF02A80, &ari, &mut a, 11_000), Push::Pending);
    assert_eq!(ext(0x0CF02D80, &accs, &mut a, 17_000), Push::Pending);
    assert_eq!(a.counters.partial, 1);
    // ARI at 21 ms completes the window opened at 17 ms: 16 ms after the last
    // sample's window (1 ms) at 100 Hz are two steps, one sample lost
    assert!(matches!(ext(0x0CF02A80, &ari, &mut a, 21_000), Push::Sample(s) if s.steps == 2));
    assert_eq!((a.counters.gaps, a.counters.lost), (1, 1));
    // a yaw figure of merit other than 0: suspect; 10 ms later: one step
    assert_eq!(ext(0x0CF02A80, &j1939([32000; 3], 0b01_0000), &mut a, 27_000), Push::Pending);
    assert!(matches!(ext(0x0CF02D80, &accs, &mut a, 28_000), Push::Sample(s) if s.suspect() && s.steps == 1));
    assert_eq!((a.counters.gaps, a.counters.suspect), (1, 1));
}

/// A DBC of the odd layouts: Motorola, a negative factor, a sign-magnitude
/// pair, rad/s and m/s^2, a 32-byte CAN FD message.
const ODD_DBC: &str = r#"VERSION ""

NS_ :

BS_:

BU_: X

BO_ 257 ESP_02: 8 X
 SG_ ESP_Gierrate : 40|14@1+ (0.01,0) [0|163.83] "Unit_DegreOfArcPerSecon" X
 SG_ ESP_VZ_Gierrate : 54|1@1+ (1,0) [0|1] "" X
 SG_ HondaYaw : 7|16@0- (-0.1,0) [-3276.8|3276.7] "deg/s" X
 SG_ Cnt : 59|4@1+ (1,0) [0|15] "" X

BO_ 2147484000 IMU_FD: 32 X
 SG_ RollRate : 0|32@1- (1e-6,0) [0|0] "rad/s" X
 SG_ PitchRate : 32|32@1- (1e-6,0) [0|0] "rad/s" X
 SG_ AX : 64|16@1- (0.001,0) [0|0] "m/s^2" X
 SG_ AY : 80|16@1- (0.001,0) [0|0] "m/s^2" X
 SG_ AZ : 96|16@1- (0.001,0) [0|0] "m/s^2" X
 SG_ Cnt : 248|4@1+ (1,0) [0|15] "" X
"#;

const ODD_TOML: &str = r#"[input]
format = "dbc"
dbc = "odd.dbc"
rate_hz = 50.0
[input.signals]
gyro_x = "IMU_FD.RollRate"
gyro_y = "-ESP_02.HondaYaw"
gyro_z = { signal = "ESP_02.ESP_Gierrate", sign_bit = "ESP_02.ESP_VZ_Gierrate" }
accel_x = "IMU_FD.AX"
accel_y = "IMU_FD.AY"
accel_z = "IMU_FD.AZ"
[input.units]
gyro = "deg/s"
[input.sample]
counter = ["ESP_02.Cnt", "IMU_FD.Cnt"]
"#;

#[test]
fn sign_magnitude_negative_factor_motorola_rad_and_can_fd() {
    // the DBC's own unit for ESP_Gierrate is not one gyrocomp knows: refused without [input.units]
    let e = plan(&ODD_TOML.replace("[input.units]\ngyro = \"deg/s\"\n", ""), ODD_DBC).unwrap_err();
    assert_eq!(e.0, "input.signals.gyro_z", "{e:?}");
    assert!(e.1.contains("t.dbc") && e.1.contains("Unit_DegreOfArcPerSecon"), "{e:?}");
    // HondaYaw's unit is deg/s but [input.units] gyro overrides every gyro: the FD roll rate is
    // then read as deg/s too; use rad/s on the FD rate by its own DBC unit instead
    let p = plan(ODD_TOML, ODD_DBC).unwrap();
    let mut a = DbcAssembler::new(Arc::new(p));
    let mut esp = [0u8; 8];
    // ESP_Gierrate raw 1234 at bits 40..53, sign bit 54 set: -12.34 deg/s
    let v: u64 = 1234 << 40 | 1 << 54 | 5 << 59;
    esp.copy_from_slice(&v.to_le_bytes());
    // HondaYaw Motorola, MSB at bit 7: bytes 0-1 big-endian, raw -50 * -0.1 = 5 deg/s, flipped: -5
    esp[0..2].copy_from_slice(&(-50i16).to_be_bytes());
    let mut fd = [0u8; 32];
    fd[0..4].copy_from_slice(&(-1_000_000i32).to_le_bytes());
    fd[8..10].copy_from_slice(&(9807i16).to_le_bytes());
    fd[31] = 5;
    assert_eq!(a.push(0, RawFrame::classic(257, &esp)), Push::Pending);
    let f = RawFrame { id: 0x160, extended: true, remote: false, fd: true, data: &fd };
    let Push::Sample(s) = a.push(0, f) else { panic!("{:?}", a.counters) };
    let close = |x: f64, y: f64| (x - y).abs() < 1e-9;
    // [input.units] gyro = deg/s applies to the FD roll rate as well: -1e6 * 1e-6 = -1 deg/s
    assert!(close(s.gyro[0], -1.0) && close(s.gyro[1], -5.0) && close(s.gyro[2], -12.34), "{s:?}");
    assert!(close(s.accel[0], 9.807 / G0), "{s:?}");
    // without the sign bit the same magnitude is positive
    esp[6] &= !(1 << 6);
    let cnt6: u64 = 6 << 59;
    esp[7] = (cnt6 >> 56) as u8;
    fd[31] = 6;
    a.push(0, RawFrame::classic(257, &esp));
    let Push::Sample(s) = a.push(0, RawFrame { id: 0x160, extended: true, remote: false, fd: true, data: &fd }) else { panic!() };
    assert!(close(s.gyro[2], 12.34), "{s:?}");
    // rad/s by the DBC's own unit when no override is given
    let p = plan(
        &ODD_TOML
            .replace("gyro = \"deg/s\"", "")
            .replace("-ESP_02.HondaYaw", "IMU_FD.PitchRate")
            .replace("{ signal = \"ESP_02.ESP_Gierrate\", sign_bit = \"ESP_02.ESP_VZ_Gierrate\" }", "\"-ESP_02.HondaYaw\""),
        ODD_DBC,
    )
    .unwrap();
    let ch = p.channels[0].unwrap();
    assert!(close(ch.a, 1e-6 * 180.0 / std::f64::consts::PI), "{ch:?}");
}

#[test]
fn the_mapping_is_refused_with_the_key_and_the_file() {
    let cases = [
        ("TX1.YawRate\"", "TX9.YawRate\"", "input.signals.gyro_z", "no message named \"TX9\""),
        ("TX1.YawRate\"", "TX1.Yaw\"", "input.signals.gyro_z", "has no signal named \"Yaw\""),
        ("gyro = \"deg/s\"", "gyro = \"rpm\"", "parse", "input.units.gyro"),
        ("\"TX3.MSG_CNT_TX3\"]", "\"TX3.AZ_STAT\", \"TX3.MSG_CNT_TX3\"]", "input.sample.counter[3]", "a second counter"),
        (", \"TX3.MSG_CNT_TX3\"]", "]", "input.sample.counter", "message TX3 has no counter"),
        ("counter = [", "window_ms = 4.0\ncounter = [", "parse", "not both"),
        ("\"TX1.YawRate_STAT\" = 0", "\"TX1.YawRate_STAT\" = 16", "input.valid", "holds 0..15"),
        ("\"TX1.YawRate_STAT\" = 0", "\"TX1.YawRate_STAT\" = 0\n\"TX9.X\" = 1", "input.valid", "no message named \"TX9\""),
        ("temp = \"TX1.TEMP_RATE_Z\"", "temp = \"TX1\"", "parse", "is not \"MESSAGE.SIGNAL\""),
    ];
    for (from, to, key, want) in cases {
        let text = MM7_TOML.replace(from, to);
        assert_ne!(text, MM7_TOML, "{from}");
        let (k, msg) = plan(&text, MM7_DBC).unwrap_err();
        assert_eq!(k, key, "{to}: {msg}");
        assert!(msg.contains(want), "{to}: {msg}");
        if key != "parse" {
            assert!(msg.contains("t.dbc") || !msg.contains(".dbc"), "{msg}");
        }
    }
    // the ADIS keys mean nothing to a DBC input
    for (extra, key) in [("[input.ids]\ngyro = 0x200\n", "input.ids"), ("", "input.profile")] {
        let text = if extra.is_empty() {
            MM7_TOML.replace("format = ", "profile = \"adis16405\"\nformat = ")
        } else {
            format!("{MM7_TOML}{extra}")
        };
        let e = Config::parse(&text, "t.toml").unwrap_err().to_string();
        assert!(e.contains(key) && e.contains("DBC"), "{e}");
    }
    // an unconvertible DBC unit names the DBC
    let (k, msg) = plan(&MM7_TOML.replace("accel = \"g\"\n", ""), &MM7_DBC.replace("\"g\" GYROCOMP", "\"furlong\" GYROCOMP")).unwrap_err();
    assert!(k == "input.signals.accel_x" && msg.contains("t.dbc") && msg.contains("furlong"), "{k}: {msg}");
}

#[test]
fn garbage_frames_are_counted_never_a_panic() {
    let mut a = DbcAssembler::new(Arc::new(plan(MM7_TOML, MM7_DBC).unwrap()));
    let mut b = DbcAssembler::new(Arc::new(plan(J1939_TOML, J1939_DBC).unwrap()));
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let mut d = [0u8; 64];
    for t in 0..200_000u64 {
        let r = next();
        for v in d.iter_mut() {
            *v = next() as u8;
        }
        let len = if r & 1 == 0 { 8 } else { (r >> 8) as usize % 65 };
        let id = [0x174, 0x178, 0x17C, 0x0CF02A80, 0x18F02D80, (r >> 16) as u32 & 0x1FFF_FFFF][(r >> 40) as usize % 6];
        let f = RawFrame { id, extended: id > 0x7FF || r & 2 != 0, remote: r & 4 != 0 && r & 8 != 0, fd: len > 8, data: &d[..len] };
        for asm in [&mut a, &mut b] {
            if let Push::Sample(s) = asm.push(t * 37, f) {
                assert!(s.gyro.iter().chain(&s.accel).all(|v| v.is_finite()) && s.temp.is_finite());
            }
        }
    }
    for c in [a.counters, b.counters] {
        assert_eq!(c.frames, 200_000);
        assert!(c.dropped() > 0, "{c:?}");
    }
    // random bytes pass a CRC-8 one time in 256: the MM7.10's frames fail it; J1939 has none
    assert!(a.counters.checksum > 10_000 && b.counters.samples > 1000, "{:?} {:?}", a.counters, b.counters);
}
