//! The documents a user reads: a README that fits on a page and names every
//! subcommand and the test command CI runs; no document pointing outside the
//! repository; every relative link resolving.

mod common;
use common::bin;
use std::path::{Path, PathBuf};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// README.md, GUIDE.md and every docs/*.md.
fn documents() -> Vec<PathBuf> {
    let mut v = vec![repo().join("README.md"), repo().join("GUIDE.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(repo().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    assert!(docs.len() >= 10, "docs/*.md: {docs:?}");
    v.extend(docs);
    v
}

#[test]
fn readme_fits_on_a_page_with_the_test_command_and_every_subcommand() {
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let n = readme.lines().count();
    assert!(n <= 200, "README.md has {n} lines (at most 200)");
    // the command .ci/run ends with, exactly as README gives it
    let ci = std::fs::read_to_string(repo().join(".ci/run")).unwrap();
    assert!(ci.contains("bash tests/run-all.sh"), ".ci/run no longer runs tests/run-all.sh");
    assert!(readme.contains("```sh\nbash tests/run-all.sh\n```"), "README.md lost the test command");
    assert!(readme.contains("scripts/fetch-realdata"), "README.md does not say how to fetch the real recordings");
    // every subcommand of `gyrocomp --help` has its row
    let help = std::process::Command::new(bin()).arg("--help").output().unwrap();
    let help = String::from_utf8(help.stdout).unwrap();
    let cmds: Vec<&str> = help
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .collect();
    assert!(cmds.len() >= 9, "{help}");
    for c in cmds {
        assert!(readme.contains(&format!("| `gyrocomp {c} ")), "README.md's command table has no row for `gyrocomp {c}`");
    }
}

#[test]
fn no_document_points_outside_the_repository() {
    for p in documents() {
        let text = std::fs::read_to_string(&p).unwrap();
        for (i, l) in text.lines().enumerate() {
            assert!(!l.contains("../shared"), "{}:{}: refers to ../shared, outside the repository: {l}", p.display(), i + 1);
        }
    }
}

#[test]
fn every_relative_link_resolves() {
    for p in documents() {
        let text = std::fs::read_to_string(&p).unwrap();
        let dir = p.parent().unwrap();
        for (i, l) in text.lines().enumerate() {
            let mut rest = l;
            while let Some(k) = rest.find("](") {
                rest = &rest[k + 2..];
                let Some(end) = rest.find(')') else { break };
                let target = &rest[..end];
                let file = target.split('#').next().unwrap();
                if !(file.is_empty() || file.contains("://") || file.starts_with("mailto:")) {
                    assert!(Path::new(dir).join(file).exists(), "{}:{}: link to {target} does not resolve", p.display(), i + 1);
                    assert!(
                        dir.join(file).canonicalize().unwrap().starts_with(repo().canonicalize().unwrap()),
                        "{}:{}: {target} is outside the repository",
                        p.display(),
                        i + 1
                    );
                }
            }
        }
    }
}
