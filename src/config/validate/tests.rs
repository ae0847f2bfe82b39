use crate::config::{bad, Config};

#[test]
fn refuses_bad_values_naming_the_key() {
    assert!(bad("[switching]\ninner = [1.02, 1.01]").contains("switching.inner"));
    assert!(bad("[switching]\ninner = [0.7, 1.01]").contains("switching.inner"));
    assert!(bad("[switching]\nouter = [nan, 1.2]").contains("switching.outer"));
    assert!(bad("[input]\nrate_hz = -5.0").contains("input.rate_hz"));
    assert!(bad("[input]\nprofile = \"adis9999\"").contains("input.profile"));
    assert!(bad("[thermal]\np1 = [0.0, inf, 0.0]").contains("thermal.p1[1]"));
    assert!(bad("[thermal]\norder = 4").contains("thermal.order"));
    assert!(bad("[thermal]\norder = 0").contains("thermal.order"));
    assert!(bad("[thermal]\np3 = [0.0, 1e-5, 0.0]").contains("thermal.p3"));
    assert!(bad("[thermal]\norder = 2\np4 = [0.0, 0.0, 1e-7]").contains("thermal.p4"));
    assert!(bad("[thermal]\norder = 3\np4 = [0.0, nan, 0.0]").contains("thermal.p4[1]"));
    assert!(bad("[thermal]\nt_min = 40.0\nt_max = 10.0").contains("thermal.t_max"));
    assert!(bad("[thermal]\nt_min = -inf").contains("thermal.t_min"));
    assert!(bad("[thermal]\nlearn_min_spread = 0.0").contains("thermal.learn_min_spread"));
    assert!(bad("[thermal]\nlearn_max_dev = [0.01, -0.01, 0.01]").contains("thermal.learn_max_dev[1]"));
    assert!(bad("[estimator]\nmode = \"magic\"").contains("mode"));
    assert!(bad("[mekf]\ngate_sigma = 0.0").contains("mekf.gate_sigma"));
    assert!(bad("[mekf]\nupdate_hz = -1.0").contains("mekf.update_hz"));
    assert!(bad("[mekf]\ndwell_s = nan").contains("mekf.dwell_s"));
    assert!(bad("[mekf]\nnhc_sigma = inf").contains("mekf.nhc_sigma"));
    assert!(bad("[mekf]\ntilt_motion_share = -0.1").contains("mekf.tilt_motion_share"));
    assert!(bad("[mekf]\nmotion_bias_walk = -0.001").contains("mekf.motion_bias_walk"));
    assert!(bad("[mekf]\nvehicle = 1").contains("vehicle"));
    assert!(bad("[mekf]\nvehicle = \"sometimes\"").contains("vehicle"));
    assert!(bad("[rest]\nmin_s = -1.0").contains("rest.min_s"));
    assert!(bad("[rest]\ngyro_dev_dps = 0.0").contains("rest.gyro_dev_dps"));
    assert!(bad("[ekf]\ninit_bias_sigma = 0.0").contains("ekf.init_bias_sigma"));
    assert!(bad("[estimator]\nuse_magnetometer = \"sometimes\"").contains("use_magnetometer"));
    assert!(bad("[mounting]\nrotation = [0.0, 95.0, 0.0]").contains("mounting.rotation[1]"));
    assert!(bad("[mounting]\nlever_arm = [0.0, nan, 0.0]").contains("mounting.lever_arm[1]"));
    assert!(bad("[speed]\ndbc = \"car.dbc\"").contains("speed.message"));
    assert!(bad("[speed]\ntimeout_s = 0.0").contains("speed.timeout_s"));
    assert!(bad("[output]\nrate_id = 0x100").contains("output.rate_id"));
}

#[test]
fn aid_id_is_checked_like_the_other_output_ids_while_it_is_sent() {
    // a clash is named at the later key, with the key it clashes with
    let e = bad("[output]\naid_id = 0x113\n");
    assert!(e.contains("line 2, column 1: output.aid_id: 0x113 is also output.status_id: the output IDs must differ"), "{e}");
    let e = bad("[output]\nbias_id = 0x110\n");
    assert!(e.contains("output.bias_id: 0x110 is also output.rate_id"), "{e}");
    // another ID moved onto the default aid_id: the default is named as such
    let e = bad("[output]\nrate_id = 0x114\n");
    assert!(e.contains("output.aid_id (not in the file: its default): 0x114 is also output.rate_id"), "{e}");
    let e = bad("[output]\naid_id = 0x103\n");
    assert!(e.contains("output.aid_id: 0x103 is also an input ID"), "{e}");
    let e = bad("[output]\naid_id = 0x800\n");
    assert!(e.contains("output.aid_id: must be an 11-bit CAN ID"), "{e}");
    // switched off, EST_AID is not sent: its ID clashes with nothing, but is still an ID
    let c = Config::parse("[output]\naid_frame = false\nrate_id = 0x114\n", "t").unwrap();
    assert!(!c.output.aid_frame && c.output.sent().all(|(k, _)| k != "output.aid_id"));
    assert!(bad("[output]\naid_frame = false\naid_id = 0x800\n").contains("output.aid_id: must be an 11-bit CAN ID"));
    let e = bad("[output]\naid_frame = 1\n");
    assert!(e.contains("line 2, column 13") && e.contains("expected true or false"), "{e}");
}

/// The values of issue 38 that passed check-config and then broke replay
/// (an allocation of 32 GB, NaN on every row, infinite samples).
#[test]
fn refuses_the_hostile_values_that_broke_replay() {
    for (text, key) in [
        ("[input]\nrate_hz = 1e9", "input.rate_hz"),
        ("[input]\nrate_hz = 1e-300", "input.rate_hz"),
        ("[input]\nrate_hz = 0.5", "input.rate_hz"),
        ("[switching]\njerk_window_s = 1e12", "switching.jerk_window_s"),
        ("[switching]\njerk_window_s = 1e6", "switching.jerk_window_s"),
        ("[input]\ngyro_lsb = 1e300", "input.gyro_lsb"),
        ("[input]\naccel_lsb = 1e300", "input.accel_lsb"),
        ("[input]\nmagn_lsb = 1e300", "input.magn_lsb"),
        ("[input]\ntemp_lsb = 1e-300", "input.temp_lsb"),
        ("[thermal]\np1 = [1e300, 0.0, 0.0]", "thermal.p1[0]"),
        ("[thermal]\np2 = [0.0, 0.0, 1e300]", "thermal.p2[2]"),
        ("[thermal]\norder = 3\np4 = [0.0, 1e300, 0.0]", "thermal.p4[1]"),
        ("[thermal]\nt0 = 1e300", "thermal.t0"),
        ("[mekf]\nzupt_sigma = 1e-300", "mekf.zupt_sigma"),
        ("[rest]\ntau_s = 1e300", "rest.tau_s"),
        ("[daemon]\nsave_every_s = 1e300", "daemon.save_every_s"),
    ] {
        let e = bad(text);
        assert!(e.contains(&format!("{key}:")) && e.contains("line "), "{text}: {e}");
        assert!(e.contains("must be within") || e.contains("must be 0"), "{text}: {e}");
    }
    // paper mode with every [ekf] sigma at 1e-300: each is refused on its own
    let sigmas = ["gyro_noise", "tilt_sigma_deg", "yaw_sigma_deg", "init_bias_sigma", "init_angle_sigma_deg"];
    let all: String = sigmas.iter().map(|k| format!("{k} = 1e-300\n")).collect();
    let e = bad(&format!("[estimator]\nmode = \"paper\"\n[ekf]\n{all}"));
    assert!(e.contains("ekf.gyro_noise") && e.contains("line 4"), "{e}");
    for k in sigmas {
        let e = bad(&format!("[estimator]\nmode = \"paper\"\n[ekf]\n{k} = 1e-300\n"));
        assert!(e.contains(&format!("ekf.{k}")), "{k}: {e}");
    }
    // the message is in a user's numbers and units
    let e = bad("[input]\ngyro_lsb = 1e300");
    assert!(e.contains("must be within 1e-5..1 deg/s per LSB, got 1e300"), "{e}");
}

#[test]
fn a_sample_of_the_physical_ranges() {
    for (text, key) in [
        ("[input]\nrate_hz = 100001.0", "input.rate_hz"),
        ("[input]\ntemp_offset = -300.0", "input.temp_offset"),
        ("[estimator]\ng0_window_s = 0.0", "estimator.g0_window_s"),
        ("[estimator]\nwarmup_s = 4000.0", "estimator.warmup_s"),
        ("[estimator]\nmax_gap_s = 0.002", "estimator.max_gap_s"),
        ("[input]\nrate_hz = 10.0\n[estimator]\nmax_gap_s = 0.05", "estimator.max_gap_s"),
        ("[ekf]\nbias_walk = 2.0", "ekf.bias_walk"),
        ("[switching]\nouter = [0.8, 30.0]", "switching.outer[1]"),
        ("[switching]\njerk_ratio = 0.0", "switching.jerk_ratio"),
        ("[thermal]\np1 = [0.0, -1.5, 0.0]", "thermal.p1[1]"),
        ("[thermal]\norder = 2\np3 = [0.02, 0.0, 0.0]", "thermal.p3[0]"),
        ("[thermal]\nt_max = 200.0", "thermal.t_max"),
        ("[thermal]\nlearn_max_dev = [0.01, 0.01, 2.0]", "thermal.learn_max_dev[2]"),
        ("[mekf]\ngate_sigma = 0.4", "mekf.gate_sigma"),
        ("[mekf]\ngate_sigma = 101.0", "mekf.gate_sigma"),
        ("[mekf]\nstop_sigma = 0.4", "mekf.stop_sigma"),
        ("[mekf]\nstop_sigma = 101.0", "mekf.stop_sigma"),
        ("[mekf]\nupdate_hz = 0.5", "mekf.update_hz"),
        ("[mekf]\ntilt_motion_share = 1.5", "mekf.tilt_motion_share"),
        ("[mekf]\nrelevel_s = 1e5", "mekf.relevel_s"),
        ("[rest]\nband = 0.6", "rest.band"),
        ("[daemon]\nsilent_after_s = 0.0", "daemon.silent_after_s"),
        ("[speed]\nscale = 20.0", "speed.scale"),
        ("[speed]\ntimeout_s = 60.0", "speed.timeout_s"),
    ] {
        let e = bad(text);
        assert!(e.contains(&format!("{key}:")), "{text}: {e}");
    }
    // the edges are in, and 0 where it means "off" or "the default"
    let c = Config::parse(
        "[input]\nrate_hz = 100000.0\nmagn_lsb = 0.0\ngyro_lsb = 1.0\n[estimator]\nmax_gap_s = 0.001\n[switching]\njerk_window_s = 10.0\n\
         [thermal]\np1 = [-1.0, 1.0, 0.0]\np2 = [100.0, 0.0, -100.0]\n[mekf]\ngate_sigma = 0.5\nmag_norm_tol = 100\nmag_dip_tol_deg = 180\n",
        "t",
    )
    .unwrap();
    assert_eq!((c.input.rate_hz, c.switching.jerk_window_s, c.mekf.gate_sigma), (100_000.0, 10.0, 0.5));
}

/// A fixed-length array with more values than the key has was read as its
/// first values, the rest dropped without a word (serde's `[f64; N]`).
#[test]
fn an_array_of_the_wrong_length_is_refused_naming_the_key_the_line_and_the_length() {
    let e = bad("[mounting]\nrotation = [0, 0, 0, 45]\n");
    assert!(e.contains("line 2") && e.contains("mounting.rotation: expected an array of 3 numbers"), "{e}");
    assert!(e.contains("got 4 values"), "{e}");
    for (text, key, n) in [
        ("[thermal]\np1 = [0.0, 0.0, 0.0, 0.01]", "thermal.p1", 3),
        ("[thermal]\np2 = [0.0, 0.0]", "thermal.p2", 3),
        ("[switching]\ninner = [0.99, 1.0, 1.01]", "switching.inner", 2),
        ("[switching]\nouter = [0.8]", "switching.outer", 2),
        ("[mounting]\nlever_arm = [0.0, 0.0, 0.0, 1.0]", "mounting.lever_arm", 3),
        ("[thermal]\nlearn_max_dev = []", "thermal.learn_max_dev", 3),
        ("mounting = { rotation = [1.0, 2.0, 3.0, 4.0, 5.0] }", "mounting.rotation", 3),
    ] {
        let e = bad(text);
        assert!(e.contains(&format!("{key}: expected an array of {n} numbers")), "{text}: {e}");
        let line = text.lines().count();
        assert!(e.contains(&format!("line {line}")), "{text}: {e}");
    }
    // the right length still loads, whole numbers included
    let c = Config::parse("[mounting]\nrotation = [0, 0, 45]\n", "t").unwrap();
    assert_eq!(c.mounting.rotation, [0.0, 0.0, 45.0]);
}

#[test]
fn a_speed_message_or_signals_without_a_dbc_is_refused() {
    let e = bad("[speed]\nsignals = [\"WHEEL_SPEED_RL\"]\n");
    assert!(e.contains("speed.signals") && e.contains("line 2") && e.contains("speed.dbc is empty"), "{e}");
    let e = bad("[speed]\nmessage = \"WHEEL_SPEEDS\"\n");
    assert!(e.contains("speed.message") && e.contains("speed.dbc is empty"), "{e}");
}

/// config/gyrocomp.toml writes the range beside every numeric key, and for
/// a single number `validate` agrees at both ends: the edge loads, 1 %
/// beyond it is refused naming the key.
#[test]
fn the_annotated_example_writes_every_range_and_validate_agrees() {
    let text = include_str!("../../../config/gyrocomp.toml");
    let mut section = "";
    let mut edges = 0;
    for line in text.lines() {
        if let Some(s) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            section = s;
            continue;
        }
        let l = line.strip_prefix("# ").unwrap_or(line);
        let Some((key, rest)) = l.split_once(" = ") else { continue };
        if key.is_empty() || !key.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_') {
            continue;
        }
        let (value, comment) = rest.split_once('#').map_or((rest.trim(), ""), |(v, c)| (v.trim(), c.trim()));
        let number = value.starts_with(|c: char| c.is_ascii_digit() || c == '-');
        let array = value.starts_with('[') && value.len() > 2 && !value.starts_with("[\"");
        let id = section == "input.ids" || key.ends_with("_id");
        if !(number || array) || id {
            continue;
        }
        assert!(comment.contains("..") || key == "order", "{section}.{key}: no range beside it: {line}");
        let range = comment.split_whitespace().find_map(|w| {
            let (a, b) = w.trim_end_matches([',', ';', ')']).split_once("..")?;
            Some((a.parse::<f64>().ok()?, b.parse::<f64>().ok()?))
        });
        let Some((lo, hi)) = range.filter(|_| number) else { continue };
        // max_gap_s must be one sample period at least: a rate of 1 Hz needs a second
        let gap = if section == "estimator" {
            "[estimator]\nmax_gap_s = 1.0\n".to_string()
        } else {
            format!("[estimator]\nmax_gap_s = 1.0\n[{section}]\n")
        };
        let at = |v: f64| Config::parse(&format!("{gap}{key} = {v:?}\n"), "t");
        let full = format!("{section}.{key}");
        for (edge, beyond) in [(lo, lo - (lo.abs() * 0.01).max(1e-9)), (hi, hi + (hi.abs() * 0.01).max(1e-9))] {
            at(edge).unwrap_or_else(|e| panic!("{full} = {edge}, the edge written in the example, is refused: {e}"));
            let e = at(beyond).err().unwrap_or_else(|| panic!("{full} = {beyond} is beyond the range {lo}..{hi} but loads"));
            assert!(e.to_string().contains(&full), "{e}");
            edges += 1;
        }
    }
    assert!(edges > 100, "only {edges} edges checked");
}
