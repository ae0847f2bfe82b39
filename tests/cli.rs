//! The command line as a newcomer meets it: `--help` of every subcommand,
//! meaningless arguments refused with the reason, `simulate --out` and
//! `evaluate --out` never destroying an input or leaving a half-written file,
//! evaluate's tables stating their windows and units, check-config.

mod common;
use common::bin;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn gyrocomp(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// `gyrocomp simulate ARGS --out D/run`, asserted to succeed; the run's directory.
fn simulated(d: &Path, args: &[&str]) -> PathBuf {
    let run = d.join("run");
    let out = run.to_str().unwrap().to_owned();
    let o = gyrocomp(&[&["simulate"], args, &["--out", &out]].concat());
    assert!(o.status.success(), "{}", text(&o.stderr));
    run
}

/// The options of a `--help` text: (flag line, description).
fn options(help: &str) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = Vec::new();
    let mut in_list = false;
    for line in help.lines() {
        if line == "Options:" || line == "Arguments:" {
            in_list = true;
            continue;
        }
        if !in_list || line.trim().is_empty() {
            continue;
        }
        let entry = line.starts_with("  -") || line.starts_with("      --") || line.starts_with("  <") || line.starts_with("  [");
        if entry {
            let t = line.trim_start();
            let (flag, desc) = match t.find("  ") {
                Some(k) => (t[..k].to_string(), t[k..].trim().to_string()),
                None => (t.to_string(), String::new()),
            };
            out.push((flag, desc));
        } else if line.starts_with("          ") {
            if let Some(last) = out.last_mut() {
                last.1 = format!("{} {}", last.1, line.trim()).trim().to_string();
            }
        } else {
            in_list = false;
        }
    }
    out
}

const SUBCOMMANDS: [&str; 9] = ["replay", "run", "check-config", "calibrate", "simulate", "evaluate", "gap", "import", "align"];

#[test]
fn every_option_of_every_subcommand_explains_itself() {
    for sub in SUBCOMMANDS {
        let o = gyrocomp(&[sub, "--help"]);
        assert!(o.status.success(), "{sub} --help");
        let help = text(&o.stdout);
        let opts = options(&help);
        assert!(opts.len() >= 2, "{sub}: no options parsed from\n{help}");
        for (flag, desc) in &opts {
            assert!(!desc.is_empty(), "{sub} {flag} has no description:\n{help}");
            if flag.contains("--help") || sub == "gap" {
                continue; // gap's help is its owner's
            }
            // every option says its default, or that it is required
            let d = desc.to_lowercase();
            assert!(d.contains("default") || d.contains("required"), "{sub} {flag}: no default and not required: {desc}");
        }
    }
}

#[test]
fn required_options_are_required_and_marked() {
    // (subcommand, what the usage line must show outside [...], the option's flag)
    let cases = [
        ("replay", "--input <IN.log> <--output <OUT.log>|--csv <EST.csv>|--mcap <OUT.mcap>>", "--input"),
        ("run", "--config <FILE>", "--config"),
        ("check-config", "<FILE>", "<FILE>"),
        ("calibrate", "--input <RUN>...", "--input"),
        ("simulate", "--scenario <NAME> --out <DIR>", "--out"),
        ("evaluate", "<--input <DIR>|--seeds <A..B>|--realdata <DIR>>", "--input"),
    ];
    for (sub, usage, flag) in cases {
        let help = text(&gyrocomp(&[sub, "--help"]).stdout);
        let line = help.lines().find(|l| l.starts_with("Usage:")).unwrap();
        assert!(line.contains(usage), "{sub}: usage {line:?} lacks {usage:?}");
        let (_, desc) = options(&help).into_iter().find(|(f, _)| f.starts_with(flag)).unwrap();
        assert!(desc.contains("Required") || desc.contains("required"), "{sub} {flag}: {desc}");
        // left out, it is refused by the parser (exit 2) before anything runs
        let o = gyrocomp(&[sub]);
        assert_eq!(o.status.code(), Some(2), "{sub} without its required options: {}", text(&o.stderr));
        assert!(text(&o.stderr).contains("required"), "{}", text(&o.stderr));
    }
    // replay with an input but neither output
    let o = gyrocomp(&["replay", "--input", "x.log"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains("--output <OUT.log>|--csv <EST.csv>|--mcap <OUT.mcap>"), "{}", text(&o.stderr));
}

#[test]
fn meaningless_arguments_are_refused_with_the_reason() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("sim");
    let out = out.to_str().unwrap();
    let cases: [(&[&str], &str); 9] = [
        (&["simulate", "--scenario", "static", "--out", out, "--duration", "-5"], "finite number of seconds > 0, got -5"),
        (&["simulate", "--scenario", "static", "--out", out, "--duration", "0"], "> 0"),
        (&["simulate", "--scenario", "static", "--out", out, "--hard"], "scenario static has none to make harder"),
        (&["simulate", "--scenario", "chamber", "--out", out, "--thermal-error", "2"], "could flip the sign of the slope"),
        (&["simulate", "--scenario", "static", "--out", out, "--thermal-error", "-0.1"], "fraction from 0 to 1"),
        (&["simulate", "--scenario", "statik", "--out", out], "unknown scenario \"statik\""),
        (&["evaluate", "--scenario", "vehicle", "--seeds", "1", "--duration", "-5"], "finite number of seconds > 0, got -5"),
        (&["evaluate", "--scenario", "paper", "--seeds", "1", "--hard"], "scenario paper has none to make harder"),
        (&["evaluate", "--scenario", "vehicle", "--seeds", "1", "--duration", "5"], "nothing to score"),
    ];
    for (args, want) in cases {
        let o = gyrocomp(args);
        let err = text(&o.stderr);
        assert!(!o.status.success(), "{args:?} accepted");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("unexpected argument"), "{args:?}: {err}");
    }
    assert!(!Path::new(out).exists(), "a refused simulate created its directory");
}

fn dir_bytes(d: &Path) -> u64 {
    let mut n = 0;
    for e in std::fs::read_dir(d).unwrap().flatten() {
        let m = e.metadata().unwrap();
        n += if m.is_dir() { dir_bytes(&e.path()) } else { m.len() };
    }
    n
}

#[test]
fn simulate_never_destroys_an_input_or_leaves_a_half_written_file() {
    let d = tempfile::tempdir().unwrap();
    let run = simulated(d.path(), &["--scenario", "static", "--duration", "20", "--seed", "3"]);
    let names = |p: &Path| {
        let mut v: Vec<String> = std::fs::read_dir(p).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
        v.sort();
        v
    };
    assert_eq!(names(&run), ["bias.csv", "config.toml", "imu.log", "scenario.toml", "sensor.toml", "truth.csv"]);
    // --model that is one of the outputs (directly or through a link) is refused, the file intact
    let sensor = run.join("sensor.toml");
    let model = std::fs::read(&sensor).unwrap();
    let link = d.path().join("model-link.toml");
    std::os::unix::fs::symlink(&sensor, &link).unwrap();
    for m in [&sensor, &link] {
        let o =
            gyrocomp(&["simulate", "--scenario", "static", "--seed", "4", "--model", m.to_str().unwrap(), "--out", run.to_str().unwrap()]);
        assert!(!o.status.success());
        assert!(text(&o.stderr).contains("refusing to overwrite an input"), "{}", text(&o.stderr));
        assert_eq!(std::fs::read(&sensor).unwrap(), model);
    }
    // a run killed half-way leaves the earlier files as they were
    let imu = std::fs::read(run.join("imu.log")).unwrap();
    let before = dir_bytes(&run);
    let mut child = Command::new(bin())
        .args(["simulate", "--scenario", "vehicle", "--duration", "3000", "--out", run.to_str().unwrap()])
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while dir_bytes(&run) < before + (2 << 20) {
        assert!(child.try_wait().unwrap().is_none(), "the long run ended before it was killed");
        assert!(t0.elapsed().as_secs() < 60, "no output after 60 s");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(std::fs::read(run.join("imu.log")).unwrap() == imu, "imu.log was overwritten by a run that did not finish");
    assert_eq!(std::fs::read(&sensor).unwrap(), model);
    // a destination that cannot be replaced is found before anything is written
    for e in std::fs::read_dir(&run).unwrap().flatten() {
        if e.file_type().unwrap().is_dir() {
            std::fs::remove_dir_all(e.path()).unwrap(); // the killed run's temporary directory
        }
    }
    std::fs::remove_file(run.join("config.toml")).unwrap();
    std::fs::create_dir(run.join("config.toml")).unwrap();
    let o = gyrocomp(&["simulate", "--scenario", "static", "--duration", "20", "--seed", "5", "--out", run.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("config.toml is a directory"), "{}", text(&o.stderr));
    assert!(std::fs::read(run.join("imu.log")).unwrap() == imu);
    assert_eq!(names(&run).len(), 6, "a temporary file or directory was left: {:?}", names(&run));
}

#[test]
fn evaluate_never_overwrites_an_input() {
    let d = tempfile::tempdir().unwrap();
    let run = simulated(d.path(), &["--scenario", "static", "--duration", "30"]);
    let truth = std::fs::read(run.join("truth.csv")).unwrap();
    // the report directory is the run directory, with report.json a link to truth.csv
    std::os::unix::fs::symlink(run.join("truth.csv"), run.join("report.json")).unwrap();
    let o = gyrocomp(&["evaluate", "--input", run.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("refusing to overwrite an input"), "{}", text(&o.stderr));
    assert_eq!(std::fs::read(run.join("truth.csv")).unwrap(), truth);
    // --config is an input too (multi-seed report)
    let rep = d.path().join("rep");
    std::fs::create_dir(&rep).unwrap();
    let cfg = rep.join("report.json");
    std::fs::write(&cfg, "[estimator]\nmode = \"paper\"\n").unwrap();
    let c = cfg.to_str().unwrap();
    let o =
        gyrocomp(&["evaluate", "--config", c, "--scenario", "static", "--seeds", "1", "--duration", "20", "--out", rep.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("refusing to overwrite an input"), "{}", text(&o.stderr));
    assert_eq!(std::fs::read_to_string(&cfg).unwrap(), "[estimator]\nmode = \"paper\"\n");
    // and a good run writes all three files and nothing else
    std::fs::remove_file(run.join("report.json")).unwrap();
    let o = gyrocomp(&["evaluate", "--input", run.to_str().unwrap(), "--out", rep.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let mut names: Vec<String> = std::fs::read_dir(&rep).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    names.sort();
    assert_eq!(names, ["attitude_error.svg", "bias.svg", "report.json"]);
}

/// A run simulated as another part (ADIS16465-1: 2 kHz, its own scales) is
/// decoded and scored with its own config.toml when no --config is given
/// (before, the built-in adis16448 at 204.8 Hz decoded it with another
/// part's scales and rate: a unit lying still scored max roll 179.6, pitch
/// 89.0 deg); a --config naming another part is refused, naming both.
#[test]
fn evaluate_decodes_a_simulated_run_as_its_own_part() {
    let d = tempfile::tempdir().unwrap();
    let run = simulated(d.path(), &["--scenario", "static", "--duration", "30", "--profile", "adis16465-1"]);
    let o = gyrocomp(&["evaluate", "--input", run.to_str().unwrap()]);
    let out = text(&o.stdout);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(out.contains("-- scored over t = 10.0..30.0 s"), "{out}");
    let row = out.lines().find(|l| l.starts_with("mekf")).unwrap_or_else(|| panic!("{out}"));
    let v: Vec<f64> = row.split_whitespace().skip(1).take(2).map(|x| x.parse().unwrap()).collect();
    assert!(v[0] < 1.0 && v[1] < 1.0, "a unit lying still, scored as its own part: max roll {} pitch {}\n{out}", v[0], v[1]);
    let cfg = d.path().join("other.toml");
    std::fs::write(&cfg, "[input]\nprofile = \"adis16448\"\n").unwrap();
    let o = gyrocomp(&["evaluate", "--input", run.to_str().unwrap(), "--config", cfg.to_str().unwrap()]);
    let err = text(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("simulated as an adis16465-1 at 2000 Hz") && err.contains("the config's part is adis16448"), "{err}");
}

/// A unit lying still that the rest detector never finds standing (its
/// noise above `[rest] gyro_dev_dps`) is said so in the replay summary,
/// with the quietest deviations against the thresholds; with the threshold
/// raised the standstill is found and the line goes. The simulator's 2-kHz
/// part (the ADIS16448's noise density, 0.74 deg/s over three axes sample
/// by sample) is found standing with the defaults: the detector sees it in
/// blocks of about 204.8 Hz (0.24 deg/s); a threshold of 0.15 is under it.
#[test]
fn replay_says_when_no_standstill_was_ever_found_and_why() {
    let d = tempfile::tempdir().unwrap();
    let run = simulated(d.path(), &["--scenario", "static", "--duration", "30", "--profile", "adis16465-1"]);
    let replay = |extra: &str| {
        let cfg = d.path().join("cfg.toml");
        std::fs::write(&cfg, std::fs::read_to_string(run.join("config.toml")).unwrap() + extra).unwrap();
        let o = gyrocomp(&[
            "replay",
            "--config",
            cfg.to_str().unwrap(),
            "--input",
            run.join("imu.log").to_str().unwrap(),
            "--csv",
            d.path().join("e.csv").to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        text(&o.stderr) + &text(&o.stdout)
    };
    let out = replay("");
    assert!(!out.contains("standstill never found") && !out.contains("standstill 0.0 s"), "{out}");
    let out = replay("\n[rest]\ngyro_dev_dps = 0.15\n");
    assert!(out.contains("standstill 0.0 s"), "{out}");
    let line = out.lines().find(|l| l.starts_with("standstill never found")).unwrap_or_else(|| panic!("{out}"));
    assert!(line.contains("([rest] gyro_dev_dps 0.15)") && line.contains("(accel_dev_g 0.050)"), "{line}");
    let quietest: f64 = line.split("gyro ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert!(quietest > 0.15 && quietest < 0.6, "{line}");
    let out = replay("\n[rest]\ngyro_dev_dps = 0.4\n");
    assert!(!out.contains("standstill never found") && !out.contains("standstill 0.0 s"), "{out}");
}

#[test]
fn evaluate_tables_state_windows_and_units_and_warn_when_a_window_is_empty() {
    // a run that ends before the manoeuvres: no manoeuvres table, no oracle floor, no inf, a warning
    let o = gyrocomp(&["evaluate", "--scenario", "vehicle", "--seeds", "5", "--duration", "60"]);
    let (out, err) = (text(&o.stdout), text(&o.stderr));
    assert!(o.status.success(), "{err}");
    assert!(out.contains("warning: no manoeuvres to score: the run ends at 60.0 s") && err.contains("warning:"), "{out}\n{err}");
    assert!(!out.contains("inf") && !out.contains("NaN"), "{out}");
    assert!(!out.contains("manoeuvres only"), "{out}");
    assert!(out.contains("-- scored over t = 10.0..60.0 s"), "{out}");
    // a single run: two tables, each with its window in the title and units under every column
    let d = tempfile::tempdir().unwrap();
    let run = simulated(d.path(), &["--scenario", "paper", "--duration", "380", "--seed", "2"]);
    let o = gyrocomp(&["evaluate", "--input", run.to_str().unwrap(), "--config", run.join("config.toml").to_str().unwrap()]);
    let out = text(&o.stdout);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let lines: Vec<&str> = out.lines().collect();
    let titles: Vec<usize> = (0..lines.len()).filter(|&k| lines[k].starts_with("-- ")).collect();
    assert_eq!(titles.len(), 2, "{out}");
    assert!(lines[titles[0]].contains("t = 10.0..380.0 s"), "{out}");
    assert!(lines[titles[1]].contains("manoeuvres only, t = 350.0..380.0 s"), "{out}");
    for &k in &titles {
        let (names, units) = (lines[k + 1], lines[k + 2]);
        assert!(names.starts_with("case") && names.contains("max pitch") && !names.contains("pitch_mx"), "{out}");
        let n_units = units.split_whitespace().count();
        assert_eq!(n_units, names.split("  ").filter(|s| !s.trim().is_empty()).count() - 1, "a column without a unit:\n{names}\n{units}");
        assert!(units.split_whitespace().all(|u| ["deg", "deg/s", "s"].contains(&u)), "{units}");
    }
    let orc = lines.iter().position(|l| l.starts_with("oracle floor")).expect("oracle floor row");
    assert!(orc > titles[1], "the oracle floor is in the manoeuvres table only:\n{out}");
}

#[test]
fn check_config_names_line_and_key_and_its_output_is_a_valid_config() {
    let d = tempfile::tempdir().unwrap();
    let bad = d.path().join("b.toml");
    std::fs::write(&bad, "# tuning\n[switching]\njerk_ratio = 0.3\ninner = [0.7, 1.3]\n").unwrap();
    let o = gyrocomp(&["check-config", bad.to_str().unwrap()]);
    assert!(!o.status.success());
    let err = text(&o.stderr);
    assert!(err.contains("b.toml, line 4, column 1: switching.inner:"), "{err}");
    let part = d.path().join("p.toml");
    std::fs::write(&part, "[input.ids]\ngyro = 0x200\n").unwrap();
    let o = gyrocomp(&["check-config", part.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let eff = text(&o.stdout);
    for want in ["rate_hz = 204.8\n", "gyro = 0x200\n", "accel = 0x101\n", "status_id = 0x113\n"] {
        assert!(eff.contains(want), "{want:?} missing:\n{eff}");
    }
    let printed = d.path().join("effective.toml");
    std::fs::write(&printed, &eff).unwrap();
    let o = gyrocomp(&["check-config", printed.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert_eq!(text(&o.stdout), eff, "the effective config is a fixed point of check-config");
}

/// `[profile.release]` ships a binary fit for a vehicle computer: no debug
/// information, symbols stripped (35.7 MB with the former `debug = 1`).
/// Checked when the tests themselves are an optimised build (`cargo test
/// --release`, as tests/run-all.sh runs them), where the binary under test is
/// the release one.
#[test]
fn release_binary_has_no_debug_info() {
    if cfg!(debug_assertions) {
        eprintln!("skipped: not a release build");
        return;
    }
    let b = std::fs::read(bin()).unwrap();
    let names = elf_section_names(&b);
    assert!(names.iter().any(|n| n == ".text"), "not an ELF64 file with sections: {names:?}");
    let debug: Vec<&String> = names.iter().filter(|n| n.starts_with(".debug") || *n == ".symtab").collect();
    assert!(debug.is_empty(), "the release binary carries {debug:?}");
    assert!(b.len() < 8 << 20, "release binary of {} bytes", b.len());
}

/// The section names of a little-endian ELF64 file.
fn elf_section_names(b: &[u8]) -> Vec<String> {
    let u16_at = |o: usize| u16::from_le_bytes([b[o], b[o + 1]]) as usize;
    let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap()) as usize;
    let u64_at = |o: usize| u64::from_le_bytes(b[o..o + 8].try_into().unwrap()) as usize;
    assert!(b.starts_with(b"\x7fELF") && b[4] == 2 && b[5] == 1, "not a little-endian ELF64 file");
    let (shoff, shentsize, shnum, shstrndx) = (u64_at(0x28), u16_at(0x3A), u16_at(0x3C), u16_at(0x3E));
    let sh = |i: usize| shoff + i * shentsize;
    let strtab = u64_at(sh(shstrndx) + 0x18);
    (0..shnum)
        .map(|i| {
            let start = strtab + u32_at(sh(i));
            let end = start + b[start..].iter().position(|&c| c == 0).unwrap();
            String::from_utf8_lossy(&b[start..end]).into_owned()
        })
        .collect()
}
