//! `gyrocomp replay` as a user runs it: the binary, real files.

mod common;
use common::{bin, gentle_log};
use std::process::Command;

fn replay(dir: &std::path::Path, input: &std::path::Path, extra: &[&str]) -> std::process::Output {
    let mut c = Command::new(bin());
    c.arg("replay").arg("--input").arg(input).arg("--output").arg(dir.join("out.log")).arg("--csv").arg(dir.join("est.csv"));
    c.args(extra);
    c.output().unwrap()
}

#[test]
fn replay_is_deterministic_and_learns_the_bias() {
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("in.log");
    std::fs::write(&input, gentle_log(204 * 40, [0.3, -0.2, 0.25], 1_700_000_000_000_000)).unwrap();
    let cfg = d.path().join("paper.toml");
    std::fs::write(&cfg, "[estimator]\nmode = \"paper\"\n").unwrap();
    let cfg_s = cfg.to_str().unwrap();
    let o1 = replay(d.path(), &input, &["--config", cfg_s]);
    assert!(o1.status.success(), "{}", String::from_utf8_lossy(&o1.stderr));
    let a = std::fs::read(d.path().join("out.log")).unwrap();
    let csv_a = std::fs::read(d.path().join("est.csv")).unwrap();
    let o2 = replay(d.path(), &input, &["--config", cfg_s]);
    assert!(o2.status.success());
    assert_eq!(a, std::fs::read(d.path().join("out.log")).unwrap(), "output log differs between runs");
    assert_eq!(csv_a, std::fs::read(d.path().join("est.csv")).unwrap(), "csv differs between runs");
    // 5 output frames per sample (EST_AID last), stamped with the closing (AUX) frame's time.
    let text = String::from_utf8(a).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 5 * 204 * 40);
    assert!(lines[4].starts_with("(1700000000.000030) can0 114#"), "{}", lines[4]);
    assert!(lines[0].starts_with("(1700000000.000030) can0 110#"), "{}", lines[0]);
    // The summary names samples and modes.
    let err = String::from_utf8_lossy(&o1.stderr);
    assert!(err.contains("samples 8160"), "{err}");
    assert!(err.contains("time per mode: fusion"), "{err}");
    // The last CSV row: bias learned on all axes.
    let csv = String::from_utf8(csv_a).unwrap();
    let last: Vec<f64> = csv.lines().last().unwrap().split(',').map(|v| v.parse().unwrap()).collect();
    for (i, want) in [0.3, -0.2, 0.25].iter().enumerate() {
        assert!((last[7 + i] - want).abs() < 0.03, "bias axis {i}: {} vs {want}", last[7 + i]);
    }
    assert!(csv.starts_with("t,roll,pitch,yaw,rate_x,rate_y,rate_z,bias_x,bias_y,bias_z,mode,temp,invalid\n"));
}

#[test]
fn bad_lines_are_counted_and_replay_goes_on() {
    let d = tempfile::tempdir().unwrap();
    let good = gentle_log(300, [0.0; 3], 1_000_000);
    let text = String::from_utf8(good).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    // a truncated line, non-hex payload, a 5-byte frame on an input ID,
    // a flipped payload byte (checksum), a DATA_CNT jump, an unknown ID
    lines[10] = lines[10][..20].to_string();
    lines[20] = lines[20].replace('#', "#ZZ").chars().take(lines[20].len()).collect();
    lines.insert(30, "(1.100000) vcan0 100#0102030405".into());
    // flip the low bit of the first payload byte of an ACCEL frame
    let flip = lines[42].clone();
    let hash = flip.find('#').unwrap();
    let c = u8::from_str_radix(&flip[hash + 2..hash + 3], 16).unwrap() ^ 1;
    lines[42] = format!("{}{:X}{}", &flip[..hash + 2], c, &flip[hash + 3..]);
    lines.insert(50, "(1.200000) vcan0 7FF#0011223344556677".into());
    lines.push("garbage \u{1}\u{2}".into());
    let input = d.path().join("bad.log");
    std::fs::write(&input, lines.join("\n")).unwrap();
    let o = replay(d.path(), &input, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("bad line 11:"), "{err}");
    assert!(err.contains("bad line 21:"), "{err}");
    assert!(err.contains("lines 1203 (bad 3)"), "{err}");
    assert!(err.contains("wrong_dlc 1"), "{err}");
    assert!(err.contains("unknown_id 1"), "{err}");
    // samples 2 (line 10), 5 (line 20) are partial, 10 fails its checksum
    assert!(err.contains("checksum 1"), "{err}");
    assert!(err.contains("samples 297"), "{err}");
}

#[test]
fn empty_missing_and_garbage_inputs_are_clear_errors() {
    let d = tempfile::tempdir().unwrap();
    let empty = d.path().join("empty.log");
    std::fs::write(&empty, b"").unwrap();
    let o = replay(d.path(), &empty, &[]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no complete sample"));

    let o = replay(d.path(), &d.path().join("nope.log"), &[]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("cannot open input") && err.contains("nope.log"), "{err}");

    // 100 MB of pseudo-random garbage, with and without newlines
    let mut g = Vec::with_capacity(100 << 20);
    let mut x: u64 = 0x9E3779B97F4A7C15;
    while g.len() < (100 << 20) {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        g.extend_from_slice(&x.to_le_bytes());
    }
    let garbage = d.path().join("garbage.log");
    std::fs::write(&garbage, &g).unwrap();
    let o = replay(d.path(), &garbage, &[]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no complete sample"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn replay_never_destroys_its_input_or_leaves_a_half_written_output() {
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("in.log");
    let log = gentle_log(300, [0.0; 3], 1_000_000);
    std::fs::write(&input, &log).unwrap();
    // --output is the input, directly and through a symbolic link
    let link = d.path().join("link.log");
    std::os::unix::fs::symlink(&input, &link).unwrap();
    for out in [&input, &link] {
        let o = Command::new(bin()).arg("replay").arg("--input").arg(&input).arg("--output").arg(out).output().unwrap();
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("refusing to overwrite an input"), "{err}");
        assert_eq!(std::fs::read(&input).unwrap(), log, "input changed");
    }
    // --output or --csv that is the --config file
    let cfg = d.path().join("c.toml");
    std::fs::write(&cfg, "[estimator]\nmode = \"paper\"\n").unwrap();
    for flag in ["--output", "--csv"] {
        let o =
            Command::new(bin()).arg("replay").arg("--config").arg(&cfg).arg("--input").arg(&input).arg(flag).arg(&cfg).output().unwrap();
        assert!(!o.status.success());
        assert!(String::from_utf8_lossy(&o.stderr).contains("refusing to overwrite an input"), "{flag}");
        assert_eq!(std::fs::read_to_string(&cfg).unwrap(), "[estimator]\nmode = \"paper\"\n", "{flag} overwrote the config");
    }
    std::fs::remove_file(&cfg).unwrap();
    // a run that fails (no sample in the input) leaves an existing output as it was
    let out = d.path().join("out.log");
    std::fs::write(&out, b"earlier result\n").unwrap();
    let empty = d.path().join("empty.log");
    std::fs::write(&empty, b"").unwrap();
    let o = Command::new(bin()).arg("replay").arg("--input").arg(&empty).arg("--output").arg(&out).output().unwrap();
    assert!(!o.status.success());
    assert_eq!(std::fs::read(&out).unwrap(), b"earlier result\n");
    let names: Vec<_> = std::fs::read_dir(d.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names.len(), 4, "a temporary file was left: {names:?}");
}

#[test]
fn counter_jump_of_1000_is_a_counted_gap() {
    let d = tempfile::tempdir().unwrap();
    let text = String::from_utf8(gentle_log(400, [0.0; 3], 1_000_000)).unwrap();
    // renumber samples 200.. by +1000 (DATA_CNT and checksum re-encoded)
    let mut out = Vec::new();
    let lines: Vec<&str> = text.lines().collect();
    for (k, group) in lines.chunks(4).enumerate() {
        let fr: Vec<_> = group.iter().map(|l| gyrocomp::candump::parse_line(l.as_bytes()).unwrap()).collect();
        let mut data: [[u8; 8]; 4] = [0, 1, 2, 3].map(|i| fr[i].payload().try_into().unwrap());
        if k >= 200 {
            for (i, d) in data.iter_mut().enumerate() {
                let pos = if i == 3 { 4 } else { 6 };
                let c = u16::from_le_bytes([d[pos], d[pos + 1]]).wrapping_add(1000);
                d[pos..pos + 2].copy_from_slice(&c.to_le_bytes());
            }
            let cs = gyrocomp::adis::checksum(&data);
            data[3][6..8].copy_from_slice(&cs.to_le_bytes());
        }
        for i in 0..4 {
            gyrocomp::candump::write_line(&mut out, fr[i].t_us, fr[i].iface, fr[i].id, &data[i]);
        }
    }
    let input = d.path().join("jump.log");
    std::fs::write(&input, out).unwrap();
    let o = replay(d.path(), &input, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("samples 400"), "{err}");
    assert!(err.contains("lost 1000 in 1 gaps"), "{err}");
    assert!(err.contains("checksum 0"), "{err}");
}

#[test]
fn check_config_prints_effective_config_and_refuses_bad_ones() {
    let d = tempfile::tempdir().unwrap();
    let good = d.path().join("g.toml");
    std::fs::write(&good, "[switching]\njerk_ratio = 0.3\n").unwrap();
    let o = Command::new(bin()).arg("check-config").arg(&good).output().unwrap();
    assert!(o.status.success());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("jerk_ratio = 0.3") && out.contains("inner = [0.985, 1.015]"), "{out}");
    let bad = d.path().join("b.toml");
    std::fs::write(&bad, "[switching]\ninner = [0.7, 1.3]\n").unwrap();
    let o = Command::new(bin()).arg("check-config").arg(&bad).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("switching.inner"));
    // the shipped example is valid
    let o = Command::new(bin()).arg("check-config").arg(concat!(env!("CARGO_MANIFEST_DIR"), "/config/gyrocomp.toml")).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn threaded_replay_writes_the_same_bytes_as_single_threaded() {
    use gyrocomp::candump::LogWriter;
    use gyrocomp::config::Config;
    use gyrocomp::pipeline::Pipeline;
    use gyrocomp::replay::{run, run_threaded, ReplaySink};
    // a long clean log with bad lines, FD, remote, extended and error frames sprinkled in
    let text = String::from_utf8(gentle_log(204 * 120, [0.2, 0.1, -0.3], 1_000_000)).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    for (k, extra) in [
        (100, "(1.100000) vcan0 100#010203"),
        (5000, "(2.000000) vcan0 100##1AABBCCDDEEFF001122"),
        (9000, "garbage"),
        (12000, "(3.000000) vcan0 101#R"),
        (15000, "(4.000000) vcan0 12345678#0011223344556677"),
        (20000, "(5.000000) vcan0 20000004#0004000000000000"),
    ] {
        lines.insert(k, extra.to_string());
    }
    let input = lines.join("\n").into_bytes();
    let cfg = Config::parse("[estimator]\nwarmup_s = 2.0\nlearn_s = 10.0", "t").unwrap();
    let go = |threaded: bool| {
        let mut w = LogWriter::new(Vec::new(), "can0");
        let mut csv = Vec::new();
        let mut pipe = Pipeline::new(&cfg);
        let mut sink = ReplaySink::<Vec<u8>, Vec<u8>> { log: Some(&mut w), csv: Some(&mut csv), keep: None, mcap: None, err: None };
        let s = if threaded { run_threaded(&mut pipe, &input[..], &mut sink) } else { run(&mut pipe, &input[..], &mut sink) }.unwrap();
        (w.finish().unwrap(), csv, s.render())
    };
    let (a, ac, asum) = go(false);
    let (b, bc, bsum) = go(true);
    assert!(
        asum.contains("(bad 1)") && asum.contains("error frames 1") && asum.contains("wrong_dlc 1") && asum.contains("unknown_id 3"),
        "{asum}"
    );
    assert_eq!(asum, bsum);
    assert_eq!(ac, bc);
    assert!(a == b, "output logs differ");
    assert_eq!(a.iter().filter(|&&c| c == b'\n').count(), 5 * 204 * 120);
}

/// (id, payload) of every frame of a candump log, in order.
fn out_frames(p: &std::path::Path) -> Vec<(u32, [u8; 8])> {
    let text = std::fs::read_to_string(p).unwrap();
    text.lines()
        .map(|l| {
            let f = gyrocomp::candump::parse_line(l.as_bytes()).unwrap_or_else(|e| panic!("{}: {e}: {l}", p.display()));
            (f.id, f.payload().try_into().unwrap())
        })
        .collect()
}

/// `[output] aid_frame = false`: four frames a sample, the very bytes of the
/// first four of the five sent by default; `aid_id` moves EST_AID.
#[test]
fn est_aid_can_be_switched_off_or_moved_and_the_other_frames_stay_as_they_were() {
    let d = tempfile::tempdir().unwrap();
    let input = d.path().join("in.log");
    std::fs::write(&input, gentle_log(204 * 10, [0.3, -0.2, 0.25], 1_700_000_000_000_000)).unwrap();
    let run = |cfg_text: &str| {
        let cfg = d.path().join("c.toml");
        std::fs::write(&cfg, cfg_text).unwrap();
        let o = replay(d.path(), &input, &["--config", cfg.to_str().unwrap()]);
        assert!(o.status.success(), "{cfg_text}: {}", String::from_utf8_lossy(&o.stderr));
        out_frames(&d.path().join("out.log"))
    };
    let five = run("");
    let four = run("[output]\naid_frame = false\n");
    let moved = run("[output]\naid_id = 0x120\n");
    assert_eq!(five.len(), 5 * 2040);
    assert_eq!(four.len(), 4 * 2040);
    let ids = |f: &[(u32, [u8; 8])]| f.iter().map(|x| x.0).collect::<Vec<_>>();
    for k in 0..2040 {
        assert_eq!(ids(&five[5 * k..5 * k + 5]), [0x110, 0x111, 0x112, 0x113, 0x114], "sample {k}");
        assert_eq!(four[4 * k..4 * k + 4], five[5 * k..5 * k + 4], "sample {k}: the four frames changed with aid_frame = false");
        assert_eq!(moved[5 * k + 4], (0x120, five[5 * k + 4].1), "sample {k}: EST_AID at aid_id");
    }
}

/// A simulated city drive that starts parked (the truth's speed 0 for its
/// first 6.4 s): replayed, its EST_AID frames say the zero velocity was fused
/// at the standstill, and not while moving; the heading is fused with the
/// magnetometer, and not applicable at every sample of a run without it.
#[test]
fn est_aid_says_zero_velocity_fused_at_the_standstill_and_heading_only_with_the_magnetometer() {
    use gyrocomp::estimator::mekf::Aid;
    use gyrocomp::output::decode_aid;
    let d = tempfile::tempdir().unwrap();
    let sim = d.path().join("sim");
    let o = Command::new(bin())
        .args(["simulate", "--scenario", "urban", "--seed", "1", "--duration", "60", "--out"])
        .arg(&sim)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let speed = gyrocomp::sim::read_vehicle_speed(&sim.join("vehicle.csv")).unwrap();
    let rate = 204.8;
    let sim_cfg = std::fs::read_to_string(sim.join("config.toml")).unwrap();
    // per sample: the codes of zero_velocity and heading, as the EST_AID frames say
    let codes = |cfg_text: String| -> Vec<(u32, u32)> {
        let cfg = d.path().join("c.toml");
        std::fs::write(&cfg, cfg_text).unwrap();
        let o = replay(d.path(), &sim.join("imu.log"), &["--config", cfg.to_str().unwrap()]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let f = out_frames(&d.path().join("out.log"));
        assert_eq!(f.len(), 5 * speed.len(), "five frames for each of the {} samples", speed.len());
        f.chunks(5)
            .map(|s| {
                assert_eq!((s[3].0, s[4].0), (0x113, 0x114));
                let (w, cnt) = decode_aid(&s[4].1);
                assert_eq!(cnt, u16::from_le_bytes([s[3].1[4], s[3].1[5]]), "EST_AID's DataCnt is EST_STATUS's");
                (w.code(Aid::ZeroVelocity), w.code(Aid::Heading))
            })
            .collect()
    };
    // the parked start: from 2.5 s (the rest detector's 1 s and its filter
    // settled) to the end of the stop
    let stop_end = speed.iter().position(|v| *v != 0.0).unwrap();
    assert!(stop_end as f64 / rate > 6.0, "the drive starts parked for {} s", stop_end as f64 / rate);
    let at_rest = (2.5 * rate) as usize..stop_end;
    let moving: Vec<usize> = (0..speed.len()).filter(|k| speed[*k].abs() > 1.0).collect();
    assert!(moving.len() as f64 / rate > 40.0, "{} s moving", moving.len() as f64 / rate);

    for (what, cfg_text) in
        [("magnetometer", sim_cfg.clone()), ("no magnetometer", format!("{sim_cfg}\n[estimator]\nuse_magnetometer = false\n"))]
    {
        let c = codes(cfg_text);
        let zv_rest = at_rest.clone().filter(|k| c[*k].0 == 1).count();
        assert_eq!(zv_rest, at_rest.len(), "{what}: zero_velocity fused at {zv_rest} of {} standstill samples", at_rest.len());
        let zv_moving = moving.iter().filter(|k| c[**k].0 != 0).count();
        assert_eq!(zv_moving, 0, "{what}: zero_velocity applicable at {zv_moving} samples moving");
        let heading_fused = c.iter().filter(|x| x.1 == 1).count();
        if what == "magnetometer" {
            assert!(heading_fused > c.len() / 2, "heading fused at {heading_fused} of {} samples", c.len());
        } else {
            let heading_any = c.iter().filter(|x| x.1 != 0).count();
            assert_eq!(heading_any, 0, "no magnetometer: heading fused or refused at {heading_any} samples");
        }
    }
}
