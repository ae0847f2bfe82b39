//! What `gap` with several trials prints and writes: `trials.md` (the
//! printed text), `trials.json`, `model.toml` (the joint model) in `--out`.

use super::trials::{HeldOut, Joint, TermRow, Trial, CONSISTENCY_LEVEL};
use crate::outfile;
use std::path::Path;

/// A coefficient with its 95 % interval.
fn pm(c: f64, se: f64) -> String {
    format!("{c:+.3e} ± {:.1e}", 1.96 * se)
}

/// The per-trial table and the verdicts.
fn effects_table(trials: &[Trial], rows: &[TermRow]) -> String {
    let mut s = String::from("| term | unit |");
    for t in trials {
        s += &format!(" {} |", t.name);
    }
    s += " chi2 / 1 % value (dof) | joint | verdict |\n|---|---|";
    s += &"---|".repeat(trials.len() + 3);
    s += "\n";
    for r in rows {
        s += &format!("| `{}` | {} |", r.term, r.unit);
        for p in &r.per_trial {
            s += &format!(" {}{} |", pm(p.coefficient, p.std_error), if p.named { " *" } else { "" });
        }
        s += &format!(
            " {:.1} / {:.1} ({}) | {} (t = {:.1}) | {} |\n",
            r.chi2,
            r.chi2_critical,
            r.dof,
            pm(r.joint, r.joint_std_error),
            r.joint_t,
            r.verdict
        );
    }
    s
}

/// The leave-one-trial-out table.
fn loo_table(loo: &[HeldOut]) -> String {
    let mut s = String::from(
        "| held-out trial | model fitted on the others adds | axis | base RMS 1-s, deg/s | extended RMS 1-s, deg/s | change |\n|---|---|---|---|---|---|\n",
    );
    for h in loo {
        if h.axes.is_empty() {
            s += &format!("| {} | nothing | - | - | - | - |\n", h.trial);
        }
        for a in &h.axes {
            let k = ["x", "y", "z"].iter().position(|x| x == a).unwrap_or(0);
            let (b, e) = (h.rms_base[k], h.rms_extended[k]);
            s += &format!("| {} | {} | {a} | {b:.5} | {e:.5} | {:+.1} % |\n", h.trial, h.added.join(", "), 100.0 * (e - b) / b);
        }
    }
    let (mut n, mut down) = (0, 0);
    for h in loo {
        for a in &h.axes {
            let k = ["x", "y", "z"].iter().position(|x| x == a).unwrap_or(0);
            n += 1;
            down += usize::from(h.rms_extended[k] < h.rms_base[k]);
        }
    }
    s + &format!("\nleave-one-out: the residual shrinks on {down} of {n} named (trial, axis) pairs\n")
}

/// The whole text.
pub fn render(trials: &[Trial], rows: &[TermRow], loo: &[HeldOut], model: &Path, out: &Path) -> String {
    let mut s = format!("# Model gap over {} trials of one unit (base model `{}`)\n\n", trials.len(), model.display());
    s += "| trial | samples | s | rate Hz | mount roll, pitch deg | found alone |\n|---|---|---|---|---|---|\n";
    for t in trials {
        let i = &t.data.info;
        let m = i.mount.as_ref().map_or("-".to_string(), |m| format!("{:+.3}, {:+.3}", m.roll_deg, m.pitch_deg));
        let found: Vec<&str> = t.result.report.findings.iter().map(|f| f.term.as_str()).collect();
        let r = &t.result.report;
        s += &format!("| {} | {} | {:.1} | {:.2} | {m} | {} |\n", t.name, r.samples, r.duration_s, i.rate_hz, found.join(", "));
    }
    s += &format!(
        "\n## Each effect per trial (95 % interval; * named by that trial alone), consistency (chi-square at {} %) and the joint estimate\n\n",
        100.0 * CONSISTENCY_LEVEL
    );
    if rows.is_empty() {
        s += "nothing was named on any trial\n";
    } else {
        s += &effects_table(trials, rows);
    }
    s += "\n## Leave-one-trial-out: the model fitted on the other trials, on the held-out one\n\n";
    s += &loo_table(loo);
    s += &format!("\nwrote {}/trials.md, trials.json, model.toml (the joint model) and a folder per trial\n", out.display());
    s
}

/// Write the files (temp-and-rename; an input is never an output).
pub fn write(out: &Path, inputs: &[&Path], text: &str, joint: &Joint) -> Result<(), String> {
    let paths = [out.join("trials.md"), out.join("trials.json"), out.join("model.toml")];
    outfile::refuse_inputs_as_outputs(inputs, &paths.iter().map(|p| p.as_path()).collect::<Vec<_>>())?;
    outfile::create_dir(out).map_err(|e| format!("--out {}: {e}", out.display()))?;
    let json = serde_json::to_string_pretty(&joint.to_json()).map_err(|e| e.to_string())? + "\n";
    for (p, bytes) in paths.iter().zip([text.as_bytes(), json.as_bytes(), joint.model.to_toml().as_bytes()]) {
        outfile::write_atomic(p, bytes).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    Ok(())
}
