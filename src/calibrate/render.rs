//! The report, the `[thermal]` section `--write` emits, and the curve.

use super::{CalError, Calibration, Levels, RunReport, Warmup, AXES, CUT_TAUS, INTERVAL_METHOD};
use crate::config::ThermalConfig;
use crate::thermal::Thermal;
use std::fmt::Write as _;
use std::path::Path;

impl Calibration {
    /// The fitted curve as a config section (no learning settings: defaults).
    pub fn thermal_config(&self) -> ThermalConfig {
        let c = |k: usize| [0, 1, 2].map(|i| self.axes[i].coeffs.get(k).copied().unwrap_or(0.0));
        ThermalConfig {
            t0: self.t0,
            p1: c(0),
            p2: [0, 1, 2].map(|i| self.axes[i].p2),
            order: self.order,
            p3: c(1),
            p4: c(2),
            t_min: Some(self.range.0),
            t_max: Some(self.range.1),
            ..ThermalConfig::default()
        }
    }

    pub fn thermal(&self) -> Thermal {
        Thermal::new(&self.thermal_config())
    }

    /// The `[thermal]` section `--write` emits; a config file accepts it as it is.
    pub fn to_toml(&self) -> String {
        let th = self.thermal_config();
        let arr = |a: [f64; 3]| format!("[{:?}, {:?}, {:?}]", a[0], a[1], a[2]);
        let mut s = String::new();
        let used = self.runs.iter().filter(|r| r.used).count();
        let _ = writeln!(
            s,
            "# gyrocomp calibrate: {used} of {} run(s), order {}, {} s of data used",
            self.runs.len(),
            self.order,
            self.bins_used
        );
        for r in &self.runs {
            if r.used {
                let _ = writeln!(s, "#   {}: warm-up cut {:.0} s, used {:.1}..{:.1} deg C", r.name, r.cut_s, r.used_temp.0, r.used_temp.1);
            } else {
                let _ = writeln!(s, "#   {}: left out ({})", r.name, r.left_out.as_deref().unwrap_or(""));
            }
        }
        let _ = writeln!(s, "# b(T) = p2 + p1 (T - t0) + p3 (T - t0)^2 + p4 (T - t0)^3, deg/s; clamped outside [t_min, t_max]");
        let _ = writeln!(s, "# p2 is the mean turn-on bias of the runs at t0 (it changes at every power-on).");
        let _ = writeln!(s, "[thermal]");
        let _ = writeln!(s, "t0 = {:?}", th.t0);
        let _ = writeln!(s, "order = {}", th.order);
        let _ = writeln!(s, "p1 = {}", arr(th.p1));
        let _ = writeln!(s, "p2 = {}", arr(th.p2));
        if self.order >= 2 {
            let _ = writeln!(s, "p3 = {}", arr(th.p3));
        }
        if self.order >= 3 {
            let _ = writeln!(s, "p4 = {}", arr(th.p4));
        }
        let _ = writeln!(s, "t_min = {:?}", self.range.0);
        let _ = writeln!(s, "t_max = {:?}", self.range.1);
        s
    }

    /// Write the `[thermal]` section to `path` (never half-written).
    pub fn write_toml(&self, path: &Path) -> Result<(), CalError> {
        crate::outfile::write_atomic(path, self.to_toml().as_bytes())
            .map_err(|e| CalError::Output { path: path.display().to_string(), msg: e.to_string() })
    }

    /// The human report.
    pub fn render(&self) -> String {
        let mut s = String::new();
        for (k, r) in self.runs.iter().enumerate() {
            let _ = writeln!(
                s,
                "run {} {}: {} samples, {:.0} s, {:.1}..{:.1} deg C{}",
                k + 1,
                r.name,
                r.samples,
                r.duration_s,
                r.temp.0,
                r.temp.1,
                if r.bad_lines > 0 { format!(", {} bad lines skipped", r.bad_lines) } else { String::new() }
            );
            if r.stretches.len() > 1 {
                let st: Vec<String> = r.stretches.iter().map(|(a, b)| format!("{a:.0}..{b:.0}")).collect();
                let _ = writeln!(
                    s,
                    "  read as {} stretches of one power cycle (s after its first sample: {}); the bias walk spans the time jumps",
                    r.stretches.len(),
                    st.join(", ")
                );
            }
            let _ = writeln!(s, "  {}", heating_line(r));
            let _ = writeln!(s, "  {}", warmup_line(r));
            let motion = if r.is_static { "static".to_string() } else { format!("NOT STATIC ({:.0} s left out)", r.moving_s) };
            let short = if r.short_bins > 2 { format!("; {} short bins ignored", r.short_bins) } else { String::new() };
            if r.used {
                let _ = writeln!(
                    s,
                    "  used {:.0} s, {:.1}..{:.1} deg C; turn-on bias at t0 [{:.4}, {:.4}, {:.4}] deg/s; {motion}{short}",
                    r.used_s, r.used_temp.0, r.used_temp.1, r.offset[0], r.offset[1], r.offset[2],
                );
            } else {
                let _ = writeln!(s, "  LEFT OUT of the fit: {}; {motion}{short}", r.left_out.as_deref().unwrap_or(""));
            }
        }
        let used = self.runs.iter().filter(|r| r.used).count();
        let runs = if used == self.runs.len() { format!("{used} run(s)") } else { format!("{used} of {} runs", self.runs.len()) };
        let _ = writeln!(
            s,
            "fit: order {}, t0 = {} deg C, {} s of 1-s means, {runs}; 95 % intervals: {INTERVAL_METHOD}",
            self.order, self.t0, self.bins_used
        );
        let names = ["p1", "p3", "p4"];
        let units = ["deg/s/C", "deg/s/C^2", "deg/s/C^3"];
        for (i, a) in self.axes.iter().enumerate() {
            let mut line = format!("axis {}:", AXES[i]);
            for k in 0..a.coeffs.len() {
                line += &format!(" {} = {:.6e} +- {:.1e} {},", names[k], a.coeffs[k], a.ci[k], units[k]);
            }
            if a.p2_ci.is_finite() {
                line += &format!(" p2 = {:.4} +- {:.4} deg/s,", a.p2, a.p2_ci);
            } else {
                line += &format!(" p2 = {:.4} deg/s (one run: no interval),", a.p2);
            }
            line += &format!(
                " residual RMS {:.4} deg/s, range {:.1}..{:.1} deg C ({:.1} deg C); noise: white {:.4} deg/s per 1-s mean, bias walk {:.5} deg/s/sqrt(s){}; {}",
                a.rms,
                self.range.0,
                self.range.1,
                self.range.1 - self.range.0,
                a.white,
                a.walk,
                walk_upper_text(a.walk_upper),
                levels_text(a.levels)
            );
            let _ = writeln!(s, "{line}");
        }
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        s
    }
}

/// The walk's upper bound, where the interval is taken too (runs in stretches).
fn walk_upper_text(up: f64) -> String {
    if up.is_finite() && up < 0.0 {
        format!(
            " (not bounded by the few seconds within the stretches: the interval is taken at the grid's end, {:.5}, ten times the white noise per sqrt(s))",
            -up
        )
    } else if up.is_finite() && up > 0.0 {
        format!(" (95 % upper bound {up:.5}: the walk across the time jumps is bounded only by the few seconds within the stretches; the interval is taken there)")
    } else {
        String::new()
    }
}

/// How the runs' levels entered the fit.
fn levels_text(l: Levels) -> String {
    match l {
        Levels::Shared { spread, upper } => {
            format!("levels: one curve, run-to-run turn-on spread {spread:.4} deg/s (at most {upper:.4})")
        }
        Levels::PerRun { spread, posed: true } if spread.is_finite() => {
            format!("levels: each run its own (turn-on spread {spread:.4} deg/s; the runs lie in different orientations)")
        }
        Levels::PerRun { spread, .. } if spread.is_finite() => {
            format!("levels: each run its own (turn-on spread {spread:.4} deg/s, beyond the walks)")
        }
        Levels::PerRun { .. } => "levels: one run".into(),
    }
}

fn heating_line(r: &RunReport) -> String {
    let jumps = if r.stretches.len() > 1 { " (across the time jumps: the time constant is what the stretches allow)" } else { "" };
    if r.heat_tau_s.is_finite() && r.tau_limit_s < super::TAU_MAX_S {
        format!(
            "self-heating: {:+.1} deg C, tau {:.0} s{jumps} -> a warm-up transient must be faster than {:.0} s (tau / {:.0})",
            r.heat_rise_c,
            r.heat_tau_s,
            r.tau_limit_s,
            super::FAST_RATIO
        )
    } else if r.heat_tau_s.is_finite() && r.heat_rise_c.abs() >= super::MIN_RISE_C {
        format!(
            "self-heating: {:+.1} deg C, tau {:.0} s{jumps} -> warm-up transients up to {:.0} s",
            r.heat_rise_c, r.heat_tau_s, r.tau_limit_s
        )
    } else if r.heat_tau_s.is_finite() {
        format!(
            "self-heating: none found ({:+.2} deg C, under {:.0} deg C) -> warm-up transients up to {:.0} s",
            r.heat_rise_c,
            super::MIN_RISE_C,
            r.tau_limit_s
        )
    } else {
        format!(
            "self-heating: none found (temperature {:.1}..{:.1} deg C, no exponential rise) -> warm-up transients up to {:.0} s",
            r.temp.0, r.temp.1, r.tau_limit_s
        )
    }
}

fn warmup_line(r: &RunReport) -> String {
    let amp = format!("amplitude [{:.4}, {:.4}, {:.4}] deg/s ({:.1} SE)", r.amplitude[0], r.amplitude[1], r.amplitude[2], r.transient_z);
    match r.warmup {
        Warmup::None if r.tau_s == 0.0 => "warm-up: not fitted -> cut 0 s".to_string(),
        Warmup::None => format!("warm-up: no significant transient (largest {:.1} SE) -> cut 0 s", r.transient_z),
        Warmup::Cut => format!("warm-up: tau {:.0} s, {amp} -> cut {:.0} s ({CUT_TAUS:.0} tau)", r.tau_s, r.cut_s),
        Warmup::AtLimit => format!(
            "warm-up: tau at the {:.0} s limit, {amp} -> cut {:.0} s ({CUT_TAUS:.0} x limit){}",
            r.tau_s,
            r.cut_s,
            if r.slope_z.is_finite() {
                format!("; slope after the cut {:.1} SE from the other runs': kept", r.slope_z)
            } else {
                String::new()
            }
        ),
        Warmup::NotSeparable => format!(
            "warm-up: tau at the {:.0} s limit, {amp}: NOT SEPARABLE from the self-heating{}",
            r.tau_s,
            if r.slope_z.is_finite() {
                format!(" (slope after a {:.0} s cut {:.1} SE from the other runs')", r.cut_s, r.slope_z)
            } else {
                format!(" (a {:.0} s cut leaves too little)", r.cut_s)
            }
        ),
    }
}
