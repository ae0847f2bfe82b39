//! Every default is written once, in the config structs' `Default`
//! (`src/config/schema.rs`); `check-config` prints it from there. The two
//! places a user reads defaults in prose, the shipped `config/gyrocomp.toml`
//! and the `[mekf]` table of `docs/estimator.md`, are checked against it
//! here: a default changed in one place and not the others fails.

use gyrocomp::config::Config;
use std::collections::BTreeMap;

/// `section.key -> value` of a printed config (`Config::to_toml`).
fn keys(text: &str) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    let mut section = String::new();
    for line in text.lines() {
        let line = line.trim();
        if line.starts_with('[') {
            section = line.trim_matches(|c| c == '[' || c == ']').to_string();
        } else if let Some((k, v)) = line.split_once(" = ") {
            out.insert(format!("{section}.{k}"), v.to_string());
        }
    }
    out
}

fn read(rel: &str) -> String {
    let p = format!("{}/{rel}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{p}: {e}"))
}

#[test]
fn shipped_config_states_the_defaults_except_its_example_bus_and_curve() {
    let defaults = keys(&Config::default().to_toml());
    let shipped = keys(&Config::parse(&read("config/gyrocomp.toml"), "config/gyrocomp.toml").unwrap().to_toml());
    assert_eq!(defaults.keys().collect::<Vec<_>>(), shipped.keys().collect::<Vec<_>>(), "the same keys");
    // the example's own choices, not defaults: a virtual bus to try it on,
    // and a thermal curve of the kind `calibrate` writes
    let example = ["can.interface", "thermal.p1", "thermal.p2"];
    let differ: Vec<&String> = defaults.keys().filter(|k| defaults[*k] != shipped[*k]).collect();
    for k in &differ {
        assert!(example.contains(&k.as_str()), "config/gyrocomp.toml gives {k} = {} where the default is {}", shipped[*k], defaults[*k]);
    }
    assert_eq!(differ.len(), example.len(), "the example's own keys: {differ:?}");
}

#[test]
fn the_estimator_docs_table_states_every_mekf_default() {
    let defaults = keys(&Config::default().to_toml());
    let doc = read("docs/estimator.md");
    // the rows `| \`key\` | default | meaning |` after the [mekf] heading line
    let start = doc.find("| key | default | meaning |").expect("docs/estimator.md has the [mekf] table");
    let mut rows = BTreeMap::new();
    for line in doc[start..].lines().skip(2) {
        if !line.starts_with("| `") {
            break;
        }
        let cells: Vec<&str> = line.split(" | ").collect();
        let key = cells[0].trim_start_matches("| ").trim_matches('`').to_string();
        rows.insert(key, cells[1].trim_matches('`').to_string());
    }
    let mekf: Vec<&String> = defaults.keys().filter(|k| k.starts_with("mekf.")).collect();
    assert!(mekf.len() >= 30, "{mekf:?}");
    for k in mekf {
        let key = &k["mekf.".len()..];
        let doc_value = rows.get(key).unwrap_or_else(|| panic!("docs/estimator.md has no row for [mekf] {key}"));
        let want = &defaults[k];
        let same = match (doc_value.parse::<f64>(), want.parse::<f64>()) {
            (Ok(a), Ok(b)) => a == b,
            _ => doc_value == want,
        };
        assert!(same, "docs/estimator.md gives [mekf] {key} = {doc_value}, the default is {want}");
    }
    for key in rows.keys() {
        assert!(defaults.contains_key(&format!("mekf.{key}")), "docs/estimator.md has a row for [mekf] {key}, which is no key");
    }
}
