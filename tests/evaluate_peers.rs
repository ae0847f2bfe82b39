//! `gyrocomp evaluate --seeds`: the still-moving column, and the peers beside ours.

use std::process::Command;

fn evaluate(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_gyrocomp")).arg("evaluate").args(args).output().unwrap();
    assert!(out.status.success(), "evaluate {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

/// The per-seed rows of `case`: the cells split on whitespace.
fn seed_rows<'a>(text: &'a str, case: &str) -> Vec<Vec<&'a str>> {
    text.lines()
        .map(|l| l.split_whitespace().collect::<Vec<_>>())
        .filter(|c| c.len() > 2 && c[0].parse::<u64>().is_ok() && c[1] == case)
        .collect()
}

/// Column 7 of a per-seed row: "still moving".
const STILL: usize = 7;

#[test]
fn crawl_seeds_report_the_seconds_of_standstill_while_moving() {
    let text = evaluate(&["--scenario", "crawl", "--seeds", "1..2", "--duration", "120"]);
    assert!(text.contains("still moving") && text.contains("worst still moving"), "{text}");
    let rows = seed_rows(&text, "mekf");
    assert_eq!(rows.len(), 2, "{text}");
    let secs: Vec<f64> = rows.iter().map(|r| r[STILL].parse().unwrap()).collect();
    assert!(secs.iter().all(|s| s.is_finite() && *s >= 0.0 && *s <= 120.0), "{secs:?}");
    // the summary gives the worst seed's seconds (the last cell of the summary row)
    let worst = secs.iter().cloned().fold(0.0, f64::max);
    let summary = text.lines().find(|l| l.starts_with("mekf ")).unwrap();
    let cell: f64 = summary.split_whitespace().last().unwrap().parse().unwrap();
    assert!((cell - worst).abs() < 0.006, "summary {cell} vs worst seed {worst}");
}

#[test]
fn a_scenario_without_vehicle_truth_prints_no_still_moving() {
    let text = evaluate(&["--scenario", "static", "--seeds", "1", "--duration", "30"]);
    let rows = seed_rows(&text, "mekf");
    assert_eq!(rows.len(), 1, "{text}");
    assert_eq!(rows[0][STILL], "-", "{text}");
}
