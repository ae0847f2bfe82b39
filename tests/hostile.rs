//! Issue 38's commands, run against the release binary as a careful attacker
//! would: outputs of every kind of path (a FIFO, a device node of the
//! test's own, `/dev/stdout`, a symbolic link, a directory, a name at the
//! length limit), a run stopped by a signal, `calibrate --write` aimed at
//! its own config. Nothing may be lost, replaced or left behind. The host's
//! `/dev` is never written: device nodes are made in a temporary directory
//! (as root; otherwise that case is skipped, said so).

mod common;
use common::bin;
use std::ffi::CString;
use std::fs;
use std::io::Write;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const ROAD: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/road-40s.log");

fn gyrocomp(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The names in `dir`, sorted.
/// Spawn with SIGINT, SIGTERM and SIGHUP at their default action in the
/// child: a test run under `nohup` (or any parent that ignores SIGHUP)
/// passes the ignored disposition on, and the program rightly keeps a
/// signal its caller ignores, so the signal sent would never end it.
fn spawn_signalable(cmd: &mut Command) -> std::process::Child {
    use std::os::unix::process::CommandExt;
    // SAFETY: only async-signal-safe calls between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
                libc::signal(sig, libc::SIG_DFL);
            }
            Ok(())
        });
    }
    cmd.stderr(Stdio::piped()).spawn().unwrap()
}

/// The child's exit status within 30 s of signal `sig`, else it is killed
/// and the test fails (never a hang).
fn wait_or_kill(child: &mut std::process::Child, sig: i32) -> std::process::ExitStatus {
    let t0 = Instant::now();
    loop {
        if let Some(st) = child.try_wait().unwrap() {
            return st;
        }
        if t0.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("still running 30 s after signal {sig}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    v.sort();
    v
}

/// The replay of the road log to a regular file: what every other kind of
/// output must receive.
fn reference_output(dir: &Path) -> Vec<u8> {
    let p = dir.join("reference.log");
    let o = gyrocomp(&["replay", "--input", ROAD, "--output", s(&p)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let b = fs::read(&p).unwrap();
    fs::remove_file(&p).unwrap();
    b
}

fn mkfifo(p: &Path) {
    let c = CString::new(p.as_os_str().as_bytes()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo {}", p.display());
}

#[test]
fn replay_to_a_fifo_writes_it_in_place_and_it_stays_a_fifo() {
    let d = tempfile::tempdir().unwrap();
    let want = reference_output(d.path());
    let fifo = d.path().join("out.fifo");
    mkfifo(&fifo);
    let reader = {
        let p = fifo.clone();
        std::thread::spawn(move || fs::read(p).unwrap())
    };
    let o = gyrocomp(&["replay", "--input", ROAD, "--output", s(&fifo)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(reader.join().unwrap() == want, "the FIFO's reader did not receive the replay's bytes");
    assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo(), "the FIFO was replaced by a file");
    assert_eq!(names(d.path()), ["out.fifo"]);
}

#[test]
fn replay_to_a_device_node_never_replaces_it_and_a_full_one_is_an_error() {
    let d = tempfile::tempdir().unwrap();
    let null = d.path().join("null");
    let full = d.path().join("full");
    let mk = |p: &Path, minor| {
        let c = CString::new(p.as_os_str().as_bytes()).unwrap();
        unsafe { libc::mknod(c.as_ptr(), libc::S_IFCHR | 0o666, libc::makedev(1, minor)) == 0 }
    };
    if !(mk(&null, 3) && mk(&full, 7)) {
        eprintln!("skipped: cannot make device nodes here (not root); the host's /dev is never written by a test");
        return;
    }
    let o = gyrocomp(&["replay", "--input", ROAD, "--output", s(&null), "--csv", s(&null)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let o = gyrocomp(&["replay", "--input", ROAD, "--output", s(&full)]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stderr));
    let err = text(&o.stderr);
    assert!(err.contains(s(&full)) && err.contains("No space left on device"), "{err}");
    for p in [&null, &full] {
        assert!(fs::symlink_metadata(p).unwrap().file_type().is_char_device(), "{} was replaced by a file", p.display());
    }
    assert_eq!(names(d.path()), ["full", "null"]);
}

#[test]
fn replay_to_dev_stdout_writes_the_process_own_stdout() {
    let d = tempfile::tempdir().unwrap();
    let want = reference_output(d.path());
    let o = gyrocomp(&["replay", "--input", ROAD, "--output", "/dev/stdout"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(o.stdout == want, "stdout is not the replay's log ({} bytes, want {})", o.stdout.len(), want.len());
    // a shell's `>>` appends: stdout redirected to a file opened for appending
    let out = d.path().join("appended.log");
    fs::write(&out, b"kept\n").unwrap();
    let f = fs::OpenOptions::new().append(true).open(&out).unwrap();
    let st = Command::new(bin()).args(["replay", "--input", ROAD, "--output", "/dev/stdout"]).stdout(f).status().unwrap();
    assert!(st.success());
    assert!(fs::read(&out).unwrap() == [b"kept\n".as_slice(), &want].concat(), "the appended file lost its head");
}

#[test]
fn replay_through_a_symlink_keeps_the_link_and_writes_its_target() {
    let d = tempfile::tempdir().unwrap();
    let want = reference_output(d.path());
    fs::create_dir(d.path().join("real")).unwrap();
    let target = d.path().join("real/out.log");
    fs::write(&target, b"old").unwrap();
    let link = d.path().join("link.log");
    std::os::unix::fs::symlink("real/out.log", &link).unwrap();
    let o = gyrocomp(&["replay", "--input", ROAD, "--output", s(&link)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(fs::symlink_metadata(&link).unwrap().file_type().is_symlink(), "the link was replaced by a file");
    assert!(fs::read(&target).unwrap() == want);
    assert_eq!(names(&d.path().join("real")), ["out.log"]);
}

#[test]
fn an_output_that_is_a_directory_is_refused_and_leaves_nothing() {
    let d = tempfile::tempdir().unwrap();
    let sub = d.path().join("sub");
    fs::create_dir(&sub).unwrap();
    let o = gyrocomp(&["replay", "--input", ROAD, "--output", s(&sub)]);
    assert_eq!(o.status.code(), Some(1));
    let err = text(&o.stderr);
    assert!(err.contains(s(&sub)) && err.contains("is a directory"), "{err}");
    assert_eq!(names(d.path()), ["sub"]);
    assert!(names(&sub).is_empty());
}

#[test]
fn an_output_name_at_the_length_limit_is_written() {
    let d = tempfile::tempdir().unwrap();
    let want = reference_output(d.path());
    let p = d.path().join(format!("{}.log", "x".repeat(246)));
    let o = gyrocomp(&["replay", "--input", ROAD, "--output", s(&p)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(fs::read(&p).unwrap() == want);
    assert_eq!(names(d.path()).len(), 1);
}

/// Replay reading a FIFO that the test feeds and then holds open: the
/// output's temporary file exists while it waits; SIGINT, SIGTERM or SIGHUP
/// end it, by that signal, with the temporary file gone and the old output
/// as it was.
#[test]
fn a_replay_stopped_by_a_signal_leaves_no_temporary_file() {
    let head: Vec<u8> = fs::read(ROAD).unwrap().split(|b| *b == b'\n').take(400).flat_map(|l| [l, b"\n"].concat()).collect();
    for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        let d = tempfile::tempdir().unwrap();
        let fifo = d.path().join("in.fifo");
        mkfifo(&fifo);
        let out = d.path().join("out.log");
        fs::write(&out, b"previous run").unwrap();
        let mut child = spawn_signalable(Command::new(bin()).args(["replay", "--input", s(&fifo), "--output", s(&out)]));
        let mut w = fs::OpenOptions::new().write(true).open(&fifo).unwrap();
        w.write_all(&head).unwrap();
        let t0 = Instant::now();
        while names(d.path()).len() < 3 {
            assert!(t0.elapsed() < Duration::from_secs(20), "no temporary file appeared: {:?}", names(d.path()));
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(names(d.path()).iter().any(|n| n.starts_with(".out.log.tmp-")), "{:?}", names(d.path()));
        assert_eq!(unsafe { libc::kill(child.id() as i32, sig) }, 0, "kill {sig}");
        let st = wait_or_kill(&mut child, sig);
        drop(w);
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(st.signal(), Some(sig), "replay did not end by signal {sig}: {st:?}");
        assert_eq!(names(d.path()), ["in.fifo", "out.log"], "signal {sig}");
        assert_eq!(fs::read(&out).unwrap(), b"previous run");
    }
}

/// `calibrate --write` aimed at its own `--config`, directly or through a
/// link, is refused before anything is read (it replaced the user's config
/// with the [thermal] snippet); a log given twice is refused too.
#[test]
fn calibrate_never_writes_over_its_config_and_takes_a_run_once() {
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("config.toml");
    let body = "[input]\nprofile = \"adis16448\"\n[thermal]\nt0 = 25.0\n";
    fs::write(&cfg, body).unwrap();
    let link = d.path().join("link.toml");
    std::os::unix::fs::symlink(&cfg, &link).unwrap();
    let run: PathBuf = d.path().join("run.log");
    fs::copy(ROAD, &run).unwrap();
    for w in [&cfg, &link] {
        let o = gyrocomp(&["calibrate", "--config", s(&cfg), "--input", s(&run), "--write", s(w)]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o.stdout));
        assert!(text(&o.stderr).contains("refusing to overwrite an input"), "{}", text(&o.stderr));
        assert_eq!(fs::read_to_string(&cfg).unwrap(), body);
    }
    let o = gyrocomp(&["calibrate", "--input", s(&run), s(&run)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o.stderr).contains("are the same log"), "{}", text(&o.stderr));
    assert_eq!(names(d.path()), ["config.toml", "link.toml", "run.log"]);
}

/// `simulate` stopped by SIGTERM while it writes leaves `--out` as it was:
/// no staging directory, no temporary files (it left gigabytes in
/// `.simulate-*`).
#[test]
fn a_simulate_stopped_by_a_signal_leaves_its_out_directory_as_it_was() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("s");
    let mut child =
        spawn_signalable(Command::new(bin()).args(["simulate", "--scenario", "vehicle", "--duration", "3000", "--out", s(&out)]));
    let t0 = Instant::now();
    let writing = || {
        fs::read_dir(&out)
            .ok()
            .and_then(|mut r| r.next())
            .and_then(|e| e.ok())
            .is_some_and(|e| fs::read_dir(e.path()).is_ok_and(|r| r.count() >= 3))
    };
    while !writing() {
        assert!(t0.elapsed() < Duration::from_secs(20), "simulate never started writing");
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGTERM) }, 0);
    let st = wait_or_kill(&mut child, libc::SIGTERM);
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(st.signal(), Some(libc::SIGTERM), "{st:?}");
    assert!(names(&out).is_empty(), "left in --out: {:?}", names(&out));
}

/// `(seconds.micros)` of a candump line, shifted by `d` s.
fn shifted(line: &str, d: f64) -> String {
    let (t, rest) = line.strip_prefix('(').and_then(|l| l.split_once(')')).unwrap();
    format!("({:.6}){rest}", t.parse::<f64>().unwrap() + d)
}

/// Frame times that run backwards (two logs joined) are said, not taken
/// silently (the rate check saturated its span to 0 and said nothing); a
/// log too short to check the rate against says so.
#[test]
fn replay_says_when_the_frame_times_run_backwards_or_are_too_short_to_check() {
    let d = tempfile::tempdir().unwrap();
    let road = fs::read_to_string(ROAD).unwrap();
    let lines: Vec<&str> = road.lines().collect();
    let back: String =
        lines[..16000].iter().map(|l| format!("{l}\n")).chain(lines[16000..].iter().map(|l| shifted(l, -30.0) + "\n")).collect();
    let p = d.path().join("back.log");
    fs::write(&p, back).unwrap();
    let csv = d.path().join("o.csv");
    let o = gyrocomp(&["replay", "--input", s(&p), "--csv", s(&csv)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("WARNING: the frame timestamps ran backwards 1 times"), "{}", text(&o.stderr));
    let short: String = lines[..4000].iter().map(|l| format!("{l}\n")).collect();
    fs::write(&p, short).unwrap();
    let o = gyrocomp(&["replay", "--input", s(&p), "--csv", s(&csv)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("was not checked against the frame timestamps: they span 4.88 s"), "{}", text(&o.stderr));
    let o = gyrocomp(&["replay", "--input", ROAD, "--csv", s(&csv)]);
    assert!(!text(&o.stderr).contains("ran backwards") && !text(&o.stderr).contains("not checked"), "{}", text(&o.stderr));
}

/// Expect exit 1 with every one of `want` in stderr; returns stderr.
fn refused(args: &[&str], want: &[&str]) -> String {
    let o = gyrocomp(args);
    let e = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{args:?} exited {:?}: {e}", o.status);
    for w in want {
        assert!(e.contains(w), "{args:?}: no {w:?} in: {e}");
    }
    e
}

/// A 20 s static run of `simulate` in `dir/name`.
fn simulated(dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(name);
    let o = gyrocomp(&["simulate", "--scenario", "static", "--duration", "20", "--out", s(&p)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    p
}

/// Item 4: a seed range over the documented limit is refused before any
/// allocation (capacity overflow, an 800 GB allocation).
#[test]
fn evaluate_refuses_a_seed_range_over_its_limit() {
    for r in ["0..18446744073709551615", "0..100000000000", "1..10001"] {
        refused(&["evaluate", "--seeds", r, "--scenario", "static", "--duration", "1"], &["seeds, over the limit of 10000"]);
    }
}

/// Item 7: a run longer than the documented limit is refused up front with
/// its estimate, and `simulate` leaves nothing (it wrote 130 MB/s).
#[test]
fn a_run_over_the_size_limit_is_refused_up_front_with_its_estimate() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("s");
    refused(
        &["simulate", "--scenario", "static", "--duration", "1e12", "--out", s(&out)],
        &["2.048e14 samples", "PB of files", "limit of 1e7 samples"],
    );
    assert!(!out.exists(), "simulate made {}", out.display());
    refused(
        &["evaluate", "--seeds", "1", "--scenario", "static", "--duration", "1e12"],
        &["2.048e14 samples", "of memory", "limit of 4e6 samples"],
    );
}

/// Item 12: options that mean nothing to a simulate directory are refused,
/// never ignored; --align-s and --score-from beyond a log's end with
/// --reference are refused; a directory without config.toml says which
/// defaults are used; a directory given as the log of --reference is named
/// as such (it said `line 0: Is a directory`).
#[test]
fn evaluate_refuses_options_that_do_not_apply_and_says_its_defaults() {
    let d = tempfile::tempdir().unwrap();
    let run = simulated(d.path(), "run");
    for (a, want) in
        [(&["--thermal-error", "0.5"][..], "--thermal-error"), (&["--peers"][..], "--peers"), (&["--scenario", "urban"][..], "--scenario")]
    {
        refused(&[&["evaluate", "--input", s(&run)][..], a].concat(), &["does not apply", want]);
    }
    let refp = d.path().join("ref.csv");
    let rows: String = (0..=40).map(|t| format!("{t},0,0,0\n")).collect();
    fs::write(&refp, format!("t,roll,pitch,yaw\n{rows}")).unwrap();
    let base = ["evaluate", "--input", ROAD, "--reference", s(&refp)];
    refused(&[&base[..], &["--align-s", "1e9"]].concat(), &["--align-s", "past the end of the log (40.0 s)"]);
    refused(&[&base[..], &["--score-from", "1e9"]].concat(), &["--score-from", "after the end of the log (40.0 s)"]);
    refused(&["evaluate", "--input", s(&run), "--reference", s(&refp)], &["is a directory", "candump log"]);
    fs::remove_file(run.join("config.toml")).unwrap();
    let o = gyrocomp(&["evaluate", "--input", s(&run)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stdout).contains("has no config.toml and no --config was given: the built-in defaults are used (profile adis16448"));
}

/// A CSV recording of `n` samples at 200 Hz, gyro `g` deg/s on every axis.
fn recording(n: usize, g: f64) -> String {
    let mut c = String::from("t,gx,gy,gz,ax,ay,az\n");
    for i in 0..n {
        c += &format!("{:.3},{g},{g},{g},0,0,-1\n", i as f64 * 0.005);
    }
    c
}

/// Item 3: one cell beyond any real part is refused with its line and
/// column (gx = 1e300 made the gyro LSB 3.9e295: every register 0), and an
/// outlier within the range that would set a scale erasing the rest of the
/// channel is refused too, naming it; the signal alone imports.
#[test]
fn import_refuses_a_value_beyond_any_part_and_an_outlier_that_would_erase_the_signal() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("a.csv");
    let out = d.path().join("a.log");
    let with = |v: &str| recording(1000, 0.05).replacen("2.490,0.05,", &format!("2.490,{v},"), 1);
    fs::write(&csv, with("1e300")).unwrap();
    refused(
        &["import", "--csv", s(&csv), "--out", s(&out)],
        &["line 500, column gx", "beyond any real part's range", "-10000..10000 deg/s"],
    );
    fs::write(&csv, with("9000")).unwrap();
    refused(&["import", "--csv", s(&csv), "--out", s(&out)], &["line 500, column gx", "99th percentile", "round to 0"]);
    assert!(!out.exists());
    fs::write(&csv, with("0.05")).unwrap();
    let o = gyrocomp(&["import", "--csv", s(&csv), "--out", s(&out)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
}

/// Item 11: --epoch and --rate have ranges, said when refused; a negative
/// rate is a rate out of range, not an unexpected argument; a rate the
/// recording's t contradicts (every sample crowded) is refused.
#[test]
fn import_refuses_an_epoch_or_rate_out_of_range() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("a.csv");
    let out = d.path().join("a.log");
    fs::write(&csv, recording(400, 0.5)).unwrap();
    let run = |extra: &[&str]| gyrocomp(&[&["import", "--csv", s(&csv), "--out", s(&out)][..], extra].concat());
    for (a, want) in [
        (["--epoch", "10000000000000"], "0..=9999999999"),
        (["--epoch", "18446744073709551615"], "0..=9999999999"),
        (["--rate", "1e-9"], "within 1..100000 Hz"),
        (["--rate", "-5"], "within 1..100000 Hz"),
    ] {
        let o = run(&a);
        assert_eq!(o.status.code(), Some(2), "{a:?}");
        assert!(text(&o.stderr).contains(want) && !text(&o.stderr).contains("unexpected argument"), "{a:?}: {}", text(&o.stderr));
    }
    let o = run(&["--rate", "1"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(text(&o.stderr).contains("399 of the 400 samples are closer than half a period"), "{}", text(&o.stderr));
    assert!(!out.exists());
    let o = run(&["--epoch", "9999999999", "--rate", "200"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
}

/// Item 10: `evaluate --input DIR` refuses a truth.csv or bias.csv holding
/// nan or inf, or with two rows swapped, naming file, line and column (it
/// scored '-' and exited 0); an imu.log of garbage names the log and its
/// bad lines (it said '0 estimates for N truth rows').
#[test]
fn evaluate_refuses_a_damaged_run_directory_naming_the_place() {
    let d = tempfile::tempdir().unwrap();
    let run = simulated(d.path(), "run");
    let truth = fs::read_to_string(run.join("truth.csv")).unwrap();
    let bias = fs::read_to_string(run.join("bias.csv")).unwrap();
    // replace the second column of line `no` (1-based)
    let edit = |t: &str, no: usize, v: &str| -> String {
        t.lines()
            .enumerate()
            .map(|(i, l)| {
                if i + 1 == no {
                    let mut f: Vec<&str> = l.split(',').collect();
                    f[1] = v;
                    f.join(",") + "\n"
                } else {
                    format!("{l}\n")
                }
            })
            .collect()
    };
    for v in ["nan", "inf"] {
        fs::write(run.join("truth.csv"), edit(&truth, 3001, v)).unwrap();
        refused(&["evaluate", "--input", s(&run)], &["truth.csv line 3001, column roll", "not a finite number"]);
    }
    let mut swapped: Vec<&str> = truth.lines().collect();
    swapped.swap(100, 101);
    fs::write(run.join("truth.csv"), swapped.join("\n") + "\n").unwrap();
    refused(&["evaluate", "--input", s(&run)], &["truth.csv line 102, column t", "not after the previous row"]);
    fs::write(run.join("truth.csv"), &truth).unwrap();
    fs::write(run.join("bias.csv"), edit(&bias, 100, "NaN")).unwrap();
    refused(&["evaluate", "--input", s(&run)], &["bias.csv line 100, column bx", "not a finite number"]);
    fs::write(run.join("bias.csv"), &bias).unwrap();
    let garbage: String = (0..500).map(|i| format!("{:x}{}\n", i * 7919, "zz".repeat(i % 30))).collect();
    fs::write(run.join("imu.log"), garbage).unwrap();
    refused(
        &["evaluate", "--input", s(&run)],
        &["imu.log: 0 estimates", "500 of its 500 lines are not candump frames", "line 1: bad timestamp"],
    );
}

/// Item 15: `--out FILE` says the name is not a directory (it said `File
/// exists (os error 17)`); a truth.csv, reference or CSV recording that is
/// not UTF-8 names the file, line and column; a model's 1e300 is written
/// 1e300, not with 301 digits.
#[test]
fn messages_name_the_place_and_say_what_is_wrong() {
    let d = tempfile::tempdir().unwrap();
    let run = simulated(d.path(), "run");
    let file = d.path().join("afile");
    fs::write(&file, "x").unwrap();
    refused(&["simulate", "--scenario", "static", "--duration", "5", "--out", s(&file)], &["is not a directory"]);
    refused(&["evaluate", "--input", s(&run), "--out", s(&file)], &["--out", "is not a directory"]);
    let mut truth = fs::read(run.join("truth.csv")).unwrap();
    truth.extend_from_slice(b"\xff\xfe\n");
    fs::write(run.join("truth.csv"), &truth).unwrap();
    refused(&["evaluate", "--input", s(&run)], &["truth.csv: not UTF-8 text: line 4099, column 1 (byte 0xff)"]);
    let bad = d.path().join("bad.csv");
    fs::write(&bad, b"t,roll,pitch,yaw\n0,0,0,\xff\n").unwrap();
    refused(&["evaluate", "--input", ROAD, "--reference", s(&bad)], &["bad.csv: not UTF-8 text: line 2, column 7"]);
    fs::write(&bad, b"t,gx,gy,gz,ax,ay,az\n0,1,\xff\n").unwrap();
    refused(&["import", "--csv", s(&bad), "--out", s(&d.path().join("o.log"))], &["bad.csv line 2, not UTF-8 text: column 5"]);
    let model = fs::read_to_string(run.join("sensor.toml")).unwrap();
    let m = d.path().join("m.toml");
    fs::write(&m, model.replacen("gyro_white = ", "gyro_white = 1e300 #", 1)).unwrap();
    let e = refused(
        &["simulate", "--scenario", "static", "--duration", "5", "--model", s(&m), "--out", s(&d.path().join("m"))],
        &["got 1e300"],
    );
    assert!(!e.contains("00000000000"), "{e}");
}
