//! `gyrocomp evaluate --ablate`: each named rule of the default filter
//! switched off alone, next to the default; `[mekf] ablate` refuses a name
//! that is no rule; docs/estimator.md lists every rule.

mod common;
use common::{bin, realdata_dir};
use gyrocomp::estimator::mekf::Rule;
use std::process::Command;

fn run(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(bin()).args(args).output().unwrap();
    (o.status.success(), String::from_utf8_lossy(&o.stdout).into(), String::from_utf8_lossy(&o.stderr).into())
}

/// The cells of a variant's row: (roll, pitch) per column.
fn row(out: &str, variant: &str) -> Vec<(f64, f64)> {
    let line = out
        .lines()
        .find(|l| l.split('|').next().is_some_and(|c| c.trim() == variant))
        .unwrap_or_else(|| panic!("no row {variant}:\n{out}"));
    line.split('|')
        .skip(1)
        .filter(|c| c.contains('/') && !c.contains("worse"))
        .map(|c| {
            let rp = c.split_whitespace().next().unwrap();
            let (r, p) = rp.split_once('/').unwrap();
            (r.parse().unwrap(), p.parse().unwrap())
        })
        .collect()
}

#[test]
fn each_rule_switched_off_alone_is_printed_beside_the_default() {
    let (ok, out, err) = run(&[
        "evaluate",
        "--ablate",
        "--seeds",
        "2",
        "--scenario",
        "urban",
        "--power-on-moving",
        "--duration",
        "60",
        "--rules",
        "speed_hypotheses,cruise",
    ]);
    assert!(ok, "{out}{err}");
    let default = row(&out, "default");
    let bank_off = row(&out, "-speed_hypotheses");
    assert_eq!(default.len(), 1, "{out}");
    assert!(default.iter().chain(&bank_off).all(|(r, p)| r.is_finite() && p.is_finite()), "{out}");
    // a car powered on at speed without its bank of speeds is far off
    assert!(bank_off[0].0.max(bank_off[0].1) > 2.0 * default[0].0.max(default[0].1), "{out}");
    assert!(out.contains("-cruise") && out.contains("verdict"), "{out}");
    // the default row is the plain filter's
    let (ok, plain, err) = run(&["evaluate", "--seeds", "2", "--scenario", "urban", "--power-on-moving", "--duration", "60"]);
    assert!(ok, "{err}");
    let line = plain.lines().find(|l| l.starts_with("2 ") && l.contains("mekf")).unwrap_or_else(|| panic!("{plain}"));
    let v: Vec<f64> = line.split_whitespace().skip(2).take(2).map(|x| x.parse().unwrap()).collect();
    assert!((v[0] - default[0].0).abs() < 0.006 && (v[1] - default[0].1).abs() < 0.006, "{line} against {default:?}");
}

#[test]
fn a_name_that_is_no_rule_is_refused_with_the_rules() {
    let (ok, _, err) = run(&["evaluate", "--ablate", "--seeds", "1", "--scenario", "urban", "--duration", "20", "--rules", "cruse"]);
    assert!(!ok && err.contains("\"cruse\"") && err.contains("cruise"), "{err}");
    let d = tempfile::tempdir().unwrap();
    let cfg = d.path().join("c.toml");
    std::fs::write(&cfg, "[mekf]\nablate = [\"level_rate\", \"nope\"]\n").unwrap();
    let (ok, _, err) = run(&["check-config", cfg.to_str().unwrap()]);
    assert!(!ok && err.contains("mekf.ablate") && err.contains("\"nope\""), "{err}");
    std::fs::write(&cfg, "[mekf]\nablate = [\"level_rate\"]\n").unwrap();
    let (ok, _, err) = run(&["check-config", cfg.to_str().unwrap()]);
    assert!(ok, "{err}");
}

#[test]
fn the_estimator_page_lists_every_rule() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/estimator.md")).unwrap();
    for r in Rule::ALL {
        assert!(doc.contains(&format!("| `{}` |", r.name())), "docs/estimator.md has no row for rule {}", r.name());
    }
}

/// The recordings' table under ablation, where `../shared/realdata` is.
#[test]
fn the_recordings_are_weighed_too() {
    let Some(dir) = realdata_dir().filter(|d| d.join("comma2k19-rav4-60s").is_dir()) else {
        println!("skipped: ../shared/realdata/comma2k19-rav4-60s not found (set GYROCOMP_REALDATA to the folder of recordings)");
        return;
    };
    let d = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(dir.join("comma2k19-rav4-60s"), d.path().join("comma2k19-rav4-60s")).unwrap();
    let (ok, out, err) = run(&["evaluate", "--ablate", "--realdata", d.path().to_str().unwrap(), "--rules", "level_rate"]);
    assert!(ok, "{out}{err}");
    let default = row(&out, "default");
    let off = row(&out, "-level_rate");
    assert_eq!(default.len(), 1, "{out}");
    assert!(default[0].0 > 0.0 && default[0].1 > 0.0 && off[0] != default[0], "{out}");
}

/// The replay summary says which rules acted and how often; a rule
/// switched off by the config neither acts nor is counted, and the
/// estimates change.
#[test]
fn the_replay_summary_names_the_rules_that_acted() {
    let road = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/road-40s.log");
    let d = tempfile::tempdir().unwrap();
    let (a, b) = (d.path().join("a.log"), d.path().join("b.log"));
    let rules_line = |err: &str| err.lines().find(|l| l.starts_with("rules that acted")).unwrap_or_else(|| panic!("{err}")).to_string();
    let (ok, out, err) = run(&["replay", "--input", road, "--output", a.to_str().unwrap()]);
    assert!(ok, "{out}{err}");
    let line = rules_line(&(out.clone() + &err));
    assert!(line.contains("level_rate "), "{line}");
    let cfg = d.path().join("c.toml");
    std::fs::write(&cfg, "[mekf]\nablate = [\"level_rate\"]\n").unwrap();
    let (ok, out, err) = run(&["replay", "--config", cfg.to_str().unwrap(), "--input", road, "--output", b.to_str().unwrap()]);
    assert!(ok, "{out}{err}");
    let line = rules_line(&(out + &err));
    assert!(!line.contains("level_rate"), "{line}");
    assert_ne!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "switching level_rate off changed nothing");
}

/// The replay summary says which aid sources fused and which the gate
/// refused; a source whose rule is switched off does not run, and without a
/// magnetometer there is no heading. `level_roll` (which runs only without
/// a heading reference) is switched off by its ablation switch: the output
/// changes.
#[test]
fn the_replay_summary_names_the_aid_sources_and_an_ablated_one_does_not_run() {
    let road = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/road-40s.log");
    let d = tempfile::tempdir().unwrap();
    let aid_line = |err: &str| err.lines().find(|l| l.starts_with("aid sources (")).unwrap_or_else(|| panic!("{err}")).to_string();
    let replay = |cfg: &str, name: &str| {
        let c = d.path().join(format!("{name}.toml"));
        std::fs::write(&c, cfg).unwrap();
        let o = d.path().join(format!("{name}.log"));
        let (ok, out, err) = run(&["replay", "--config", c.to_str().unwrap(), "--input", road, "--output", o.to_str().unwrap()]);
        assert!(ok, "{out}{err}");
        (aid_line(&(out + &err)), std::fs::read(&o).unwrap())
    };
    let (line, _) = replay("", "default");
    for want in ["vehicle_constraint ", "level_rate ", "heading "] {
        assert!(line.contains(want), "{want}: {line}");
    }
    let (line, nomag) = replay("[estimator]\nuse_magnetometer = false\n", "nomag");
    assert!(!line.contains("heading") && line.contains("level_roll "), "{line}");
    let (line, off) = replay("[estimator]\nuse_magnetometer = false\n[mekf]\nablate = [\"level_roll\"]\n", "off");
    assert!(!line.contains("level_roll"), "{line}");
    assert_ne!(nomag, off, "switching level_roll off changed nothing");
}
