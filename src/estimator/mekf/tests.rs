//! Finite-difference checks of the measurement rows and the transition.

use super::*;

fn filter() -> Mekf {
    let p = crate::estimator::mekf_params(&crate::config::Config::default());
    let sw = Switching::new(&crate::config::SwitchingConfig::default(), 200.0);
    let mut m = Mekf::new(MekfParams { lever: [0.9, 0.1, -0.3], speed_aided: true, ..p }, sw);
    m.start(&[0.1, -0.2, -0.97], &[0.2, 0.05, 0.4], [0.01, -0.02, 0.03], [0.01; 3], true);
    m.core.set_attitude(quat::from_euler(0.2, -0.3, 1.1));
    m.core.set_velocity([8.0, -3.0, 0.5]);
    m.core.set_scale(0.02);
    m
}

/// Apply an error-state step the way `inject` does, on a copy.
fn perturbed(m: &Mekf, k: usize, eps: f64) -> Mekf {
    let mut c = m.clone();
    c.core.clear_dx();
    c.core.set_dx(k, eps);
    c.inject();
    c
}

/// Every measurement row of H against finite differences of its
/// prediction: `z_pred(x ⊕ dx) - z_pred(x) = H dx`.
#[test]
fn measurement_rows_match_finite_differences() {
    let mut m = filter();
    // the rate is the measured gyro less the bias the state holds
    let gyro = [0.05, -0.1, 0.3];
    let omega = |f: &Mekf| [gyro[0] - f.bias()[0], gyro[1] - f.bias()[1], gyro[2] - f.bias()[2]];
    let eps = 1e-6;
    // the car's axes as configured, and turned to its pull-aways (the
    // lever arm, in the car's axes, turned with them); and a free unit's
    for (vehicle, yaw) in [(true, 0.0), (true, 0.7), (false, 0.7)] {
        m.vehicle = vehicle;
        m.axes = forward_axis::VehicleAxes::new(yaw, m.p.lever);
        for axis in 0..3 {
            let (v0, h) = m.body_velocity_row(axis, &omega(&m));
            for k in 0..N {
                let p = perturbed(&m, k, eps);
                let (v1, _) = p.body_velocity_row(axis, &omega(&p));
                let fd = (v1 - v0) / eps;
                assert!((fd - h[k]).abs() < 1e-4 * (1.0 + h[k].abs()), "yaw {yaw} velocity axis {axis} state {k}: {fd} vs {}", h[k]);
            }
        }
        // the car's roll (`fuse_level_roll`), along its turned axes too
        if vehicle {
            let (r0, h) = m.car_roll_row().unwrap();
            for k in 0..N {
                let (r1, _) = perturbed(&m, k, eps).car_roll_row().unwrap();
                let fd = (r1 - r0) / eps;
                assert!((fd - h[k]).abs() < 1e-4 * (1.0 + h[k].abs()), "yaw {yaw} car roll state {k}: {fd} vs {}", h[k]);
            }
            let e = quat::euler(m.core.c());
            if yaw == 0.0 {
                assert!((r0 - e[0]).abs() < 1e-9, "the car's roll {r0} is the unit's {} with its axes", e[0]);
            }
        }
        // a car driving along its (turned) x axis, not turning: the lateral
        // and vertical rows read zero, the forward one its speed
        if vehicle {
            let mut c = m.clone();
            c.core.set_velocity(rotate(c.core.c(), &c.axes.rows[0].map(|v| v * 8.0)));
            let rows: Vec<f64> = (0..3).map(|axis| c.body_velocity_row(axis, &[0.0; 3]).0).collect();
            assert!((rows[0] - 8.0).abs() < 1e-12 && rows[1].abs() < 1e-12 && rows[2].abs() < 1e-12, "yaw {yaw}: {rows:?}");
        }
    }
    m.vehicle = true;
    m.axes = forward_axis::VehicleAxes::new(0.0, m.p.lever);
    // heading: the prediction is the heading of C m (the field fixed in NED)
    let mb = [0.1, 0.3, 0.35];
    let psi = |f: &Mekf| {
        let n = rotate(f.core.c(), &mb);
        n[1].atan2(n[0])
    };
    let n = rotate(m.core.c(), &mb);
    let h2 = n[0] * n[0] + n[1] * n[1];
    let h = [n[0] * n[2] / h2, n[1] * n[2] / h2, -1.0];
    for k in 0..3 {
        // the true state is est ⊕ dx: the heading computed with the estimate
        // differs from the truth's by -(that change)
        let fd = -(psi(&perturbed(&m, k, eps)) - psi(&m)) / eps;
        assert!((fd - h[k]).abs() < 1e-4, "heading state {k}: {fd} vs {}", h[k]);
    }
    // gravity: u = C f/|f| for the f of a level-consistent truth
    let f_true = rotate_t(m.core.c(), &[0.0, 0.0, -1.0]);
    for k in 0..3 {
        let t = perturbed(&m, k, eps);
        // f is what the true attitude sees; the estimate m rotates it
        let f = rotate_t(t.core.c(), &[0.0, 0.0, -1.0]);
        let u = rotate(m.core.c(), &f);
        let want = match k {
            0 => [0.0, -eps, 0.0],
            1 => [eps, 0.0, 0.0],
            _ => [0.0, 0.0, 0.0],
        };
        assert!((u[0] - want[0]).abs() < 1e-9 && (u[1] - want[1]).abs() < 1e-9, "gravity state {k}: {u:?}");
        let _ = f_true;
    }
}

/// The accumulated transition against propagating the state difference.
#[test]
fn transition_matches_propagating_a_perturbed_state() {
    let mut a = filter();
    let eps = 1e-6;
    let w = [0.2, -0.1, 0.4];
    let f = [0.1, 0.05, -0.98];
    let dt = 0.005;
    let steps = 8;
    let run = |m: &mut Mekf| {
        for _ in 0..steps {
            let s = StepIn {
                dt,
                t: 1.0,
                gyro: w.map(|x| x / D2R),
                accel: f,
                magn: [0.0; 3],
                temp: 25.0,
                g0: 1.0,
                dbias: [0.0; 3],
                suspect: false,
            };
            // propagate without running a tick
            let acc_t = m.acc.t;
            m.p.tick_s = 1e9;
            m.step(&s);
            let _ = acc_t;
        }
    };
    let base = a.clone();
    run(&mut a);
    // Φ from the accumulators, applied to a covariance with one unit entry
    for k in 0..N {
        let mut b = perturbed(&base, k, eps);
        run(&mut b);
        // the difference of the end states, in error coordinates
        let dq = quat::mul(b.core.q(), &[a.core.q()[0], -a.core.q()[1], -a.core.q()[2], -a.core.q()[3]]);
        let dth = [2.0 * dq[1] / eps, 2.0 * dq[2] / eps, 2.0 * dq[3] / eps];
        let db: Vec<f64> = (0..3).map(|i| (b.bias()[i] - a.bias()[i]) / eps).collect();
        let dv: Vec<f64> = (0..3).map(|i| (b.core.v()[i] - a.core.v()[i]) / eps).collect();
        // Φ column k from the accumulated blocks
        let mut p = [[0.0; N]; N];
        p[k][k] = 1.0;
        let mut m = a.clone();
        m.core.set_cov(p);
        m.propagate_noiseless();
        // P' = Φ e_k e_k^T Φ^T: column k of Φ is P'[.][k] / Φ[k][k]
        let col: Vec<f64> = (0..N).map(|i| m.core.cov()[i][k]).collect();
        let want: Vec<f64> = dth.iter().chain(db.iter()).chain(dv.iter()).copied().collect();
        for i in 0..9 {
            assert!((col[i] - want[i]).abs() < 2e-3 * (1.0 + want[i].abs()), "Φ[{i}][{k}]: {} vs {}", col[i], want[i]);
        }
    }
}

/// A car's resync widens only what the vehicle constraint cannot see: the
/// whole state turned (attitude and velocity together) and the speed along
/// the body x axis. The constraint rows' predicted variance `h P h^T` is
/// what it was before the gap; the attitude opens by at most 5 deg. A unit
/// that is not a vehicle opens its attitude by the gap's whole turn.
#[test]
fn a_cars_resync_opens_only_what_the_constraint_cannot_see() {
    let mut m = filter();
    m.vehicle = true;
    // a car drives along its x axis
    m.core.set_velocity(rotate(m.core.c(), &[8.0, 0.0, 0.0]));
    let omega = [0.0, 0.0, 0.2];
    let hph = |m: &Mekf, axis: usize| {
        let (_, h) = m.body_velocity_row(axis, &omega);
        (0..N).map(|i| (0..N).map(|j| h[i] * m.core.cov()[i][j] * h[j]).sum::<f64>()).sum::<f64>()
    };
    let before = [hph(&m, 1), hph(&m, 2)];
    let th0 = m.core.cov()[TH][TH];
    let fwd0 = *m.core.cov();
    m.resync(4.0);
    for (axis, b) in [1, 2].into_iter().zip(before) {
        let a = hph(&m, axis);
        assert!((a - b).abs() < 1e-9 * (1.0 + b), "constraint {axis}: h P h^T {b} -> {a}");
    }
    let opened = (m.core.cov()[TH][TH] - th0).sqrt();
    assert!((opened - 5.0 * D2R).abs() < 1e-12, "tilt opened by {} deg", opened / D2R);
    // the speed along the body x axis opened by 4 + (3 x 4)^2
    let cx = [m.core.c()[0][0], m.core.c()[1][0], m.core.c()[2][0]];
    let var_x = |p: &[[f64; N]; N]| (0..3).map(|i| (0..3).map(|j| cx[i] * p[VE + i][VE + j] * cx[j]).sum::<f64>()).sum::<f64>();
    assert!(
        (var_x(m.core.cov()) - var_x(&fwd0) - 148.0).abs() < 1e-9,
        "forward speed variance {} -> {}",
        var_x(&fwd0),
        var_x(m.core.cov())
    );
    assert!(m.heading.is_open() && m.lever_pending);

    let mut h = filter();
    h.vehicle = false;
    let th0 = h.core.cov()[TH + 1][TH + 1];
    h.resync(4.0);
    let opened = (h.core.cov()[TH + 1][TH + 1] - th0).sqrt();
    assert!((opened - 90.0 * D2R).abs() < 1e-12, "hand-held tilt opened by {} deg", opened / D2R);
    assert!(!h.heading.is_open());
}

/// Turning the whole state about the down axis changes nothing the body
/// sees: the body-frame velocity, the constraint rows and their predicted
/// variance, the bias; the heading moves by the angle and the velocity with it.
#[test]
fn turning_the_heading_turns_the_state_and_its_covariance_together() {
    let mut m = filter();
    m.resync(2.0);
    let omega = [0.01, -0.02, 0.3];
    let rows = |m: &Mekf| {
        [1, 2].map(|axis| {
            let (val, h) = m.body_velocity_row(axis, &omega);
            let s: f64 = (0..N).map(|i| (0..N).map(|j| h[i] * m.core.cov()[i][j] * h[j]).sum::<f64>()).sum();
            (val, s)
        })
    };
    let (vb0, r0, yaw0, b0) = (rotate_t(m.core.c(), m.core.v()), rows(&m), m.euler()[2], *m.core.bias());
    let psi = 0.7;
    m.turn_heading(psi);
    let vb1 = rotate_t(m.core.c(), m.core.v());
    for i in 0..3 {
        assert!((vb1[i] - vb0[i]).abs() < 1e-12, "body velocity {vb0:?} -> {vb1:?}");
    }
    for (a, b) in rows(&m).iter().zip(&r0) {
        assert!((a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-9 * (1.0 + b.1), "row {b:?} -> {a:?}");
    }
    let turned = wrap_pi(m.euler()[2] - yaw0);
    assert!((turned - psi).abs() < 1e-9, "heading turned by {turned}");
    assert_eq!(*m.core.bias(), b0);
    for i in 0..N {
        for j in 0..N {
            assert!((m.core.cov()[i][j] - m.core.cov()[j][i]).abs() < 1e-12, "symmetric");
        }
    }
}

/// A vehicle's vertical velocity beyond `max_vertical_speed` is held to the
/// bound, and the pitch with it (the car drives along its body x axis, so a
/// vertical velocity is a pitch); within the bound nothing changes; 0 turns
/// it off.
#[test]
fn a_vertical_speed_beyond_any_road_is_held_to_the_bound() {
    let omega = [0.0, 0.0, 0.0];
    // 16 m/s along the body x axis, pitched so that it descends at `vd`
    let run = |vd: f64, bound: f64| {
        let mut m = filter();
        m.vehicle = true;
        m.p.max_vertical_speed = bound;
        m.core.set_attitude(quat::from_euler(0.0, -(vd / 16.0).asin(), 0.5));
        m.core.set_velocity(rotate(m.core.c(), &[16.0, 0.0, 0.0]));
        m.core.clear_dx();
        m.velocity_updates(&omega, true, m.p.gate);
        m.inject();
        m
    };
    for vd in [6.0, -6.0] {
        let (off, on) = (run(vd, 0.0), run(vd, 2.0));
        assert!((off.core.v()[2] - vd).abs() < 1e-6, "without the bound the constraint is met: {}", off.core.v()[2]);
        assert!(on.core.v()[2].abs() < vd.abs() - 1.0, "held: {} against {vd} without the bound", on.core.v()[2]);
        assert!(on.core.v()[2].abs() > 2.0 - 3.0 * VERTICAL_BOUND_SIGMA, "not past the bound: {}", on.core.v()[2]);
        // the pitch moved towards level with it
        assert!(on.euler()[1].abs() < off.euler()[1].abs() - 0.01, "pitch {} vs {}", on.euler()[1], off.euler()[1]);
    }
    let (a, b) = (run(1.5, 0.0), run(1.5, 2.0));
    assert_eq!((a.core.v(), a.core.q()), (b.core.v(), b.core.q()), "within the bound nothing changes");
}

/// The covariance a 1 % gyro scale error adds over a tick: a quarter turn
/// about a horizontal axis grows the tilt's and not the heading's; the same
/// turn about the vertical grows the heading's as well.
#[test]
fn a_scale_error_turns_the_heading_only_by_the_turn_about_the_vertical() {
    use std::f64::consts::FRAC_PI_2;
    let mut m = filter();
    let (q, s) = (m.p.q_gyro, (m.p.gyro_scale * FRAC_PI_2).powi(2));
    assert!(s > 100.0 * q, "the scale term is the one tested: {s} against {q}");
    for (turned_z, heading) in [(0.0, q), (FRAC_PI_2, q + s)] {
        m.core.set_cov([[0.0; N]; N]);
        m.propagate(&Accum { t: 1.0, n: 1, turned: FRAC_PI_2, turned_z, ..Accum::default() });
        for i in 0..2 {
            assert!((m.core.cov()[TH + i][TH + i] - (q + s)).abs() < 1e-15, "tilt {i}: {}", m.core.cov()[TH + i][TH + i]);
        }
        assert!((m.core.cov()[TH + 2][TH + 2] - heading).abs() < 1e-15, "heading {} against {heading}", m.core.cov()[TH + 2][TH + 2]);
    }
}

/// The tilt innovation is the whole rotation from the measured gravity to
/// the vertical, at any size: 1 deg as near level, 120 and 179 deg whole
/// (the small-angle `u_xy` gives sin(179 deg) = 0.017 rad there: a filter
/// upside down would take itself for level).
#[test]
fn the_tilt_innovation_is_the_whole_angle_far_from_level() {
    for deg in [1.0f64, 30.0, 120.0, 179.0] {
        for az in [0.0f64, 0.7, 2.5] {
            let ang = deg.to_radians();
            let dth = [ang * az.cos(), ang * az.sin(), 0.0];
            // C_true = R(dθ) C_est: the estimate sees gravity at R(-dθ)(-e_z)
            let r = quat::to_matrix(&quat::from_rotvec(&[-dth[0], -dth[1], 0.0]));
            let u = rotate(&r, &[0.0, 0.0, -1.0]);
            let nu = tilt_innovation(&u);
            assert!((nu[0] - dth[1]).abs() < 1e-9 && (nu[1] + dth[0]).abs() < 1e-9, "{deg} deg at {az}: {nu:?} against {dth:?}");
            if deg > 170.0 {
                assert!(u[0].hypot(u[1]) < 0.02, "the small-angle reading would be {:?}", u);
            }
        }
    }
}

/// Only a vehicle cruises. A free unit whose velocity estimate has drifted
/// (a tilt error in motion integrated into it: broad-18 powered on in motion
/// with several deg/s of turn-on bias) and that then lies still is at a
/// standstill: zero velocity, re-levelled if need be, not a "smooth cruise"
/// at 3 m/s that skips the zero-velocity update and keeps the drift.
#[test]
fn a_free_unit_lying_still_is_standing_whatever_velocity_it_believes() {
    let p = crate::estimator::mekf_params(&crate::config::Config::default());
    let sw = Switching::new(&crate::config::SwitchingConfig::default(), 200.0);
    let mut m = Mekf::new(MekfParams { vehicle: Vehicle::Off, ..p }, sw);
    let bias = [0.2, -0.1, 0.05];
    m.start(&[0.0, 0.0, -1.0], &[0.2, 0.0, 0.4], [0.0; 3], [3.0 * D2R; 3], false);
    let still = |k: u32| StepIn {
        dt: if k == 0 { 0.0 } else { 0.005 },
        t: k as f64 * 0.005,
        gyro: bias,
        accel: [0.0, 0.0, -1.0],
        magn: [0.2, 0.0, 0.4],
        temp: 25.0,
        g0: 1.0,
        dbias: [0.0; 3],
        suspect: false,
    };
    let mut k = 0;
    // a first rest reads the bias
    while k < 1000 {
        m.step(&still(k));
        k += 1;
    }
    assert!(m.bias_known, "the first rest did not read the bias");
    // a moment of motion
    let mut moving = still(k);
    moving.gyro = [bias[0] + 30.0, bias[1], bias[2]];
    moving.accel = [0.3, 0.0, -1.0];
    for _ in 0..40 {
        m.step(&moving);
        k += 1;
    }
    // then it lies still again; as the detector is about to call it rest,
    // the filter believes 3 m/s north, firmly
    while m.rest.held() < 0.9 * m.p.rest.min_s {
        m.step(&still(k));
        k += 1;
    }
    m.core.set_velocity([3.0, 0.0, 0.0]);
    m.core.decorrelate(&[VE, VE + 1, VE + 2]);
    for i in 0..3 {
        m.core.set_var(VE + i, 0.01);
    }
    let mut standing = 0.0;
    for _ in 0..800 {
        let (_, fl, _) = m.step(&still(k));
        k += 1;
        if fl & flags::STANDSTILL != 0 {
            standing += 0.005;
        }
    }
    let speed = norm(m.core.v());
    println!("standstill {standing:.2} s of the last 4 s, speed believed {speed:.3} m/s");
    assert!(standing > 3.0, "standstill only {standing} s of 4");
    assert!(speed < 0.05, "the drifted velocity was kept: {speed} m/s");
}

/// A power-on speed hypothesis lies along the car's forward axis, also when
/// the axes were turned from the body's (restored after a restart): its
/// forward speed is the hypothesis, its variance along that axis is the
/// hypothesis's and across it `init_speed_sigma`'s.
#[test]
fn a_speed_hypothesis_lies_along_the_cars_axes_when_they_are_turned() {
    for yaw_deg in [0.0, 90.0, -60.0] {
        let mut m = filter();
        m.set_vehicle_axes(yaw_deg);
        m.set_speed_hypothesis(12.0, 0.5);
        assert!((m.forward_speed() - 12.0).abs() < 1e-9, "turned {yaw_deg}: forward speed {}", m.forward_speed());
        // the velocity in the car's axes: along x only
        let vb = rotate_t(m.core.c(), m.core.v());
        let rows = m.axes.rows;
        let lateral: f64 = (0..3).map(|i| rows[1][i] * vb[i]).sum();
        let vertical: f64 = (0..3).map(|i| rows[2][i] * vb[i]).sum();
        assert!(lateral.abs() < 1e-9 && vertical.abs() < 1e-9, "turned {yaw_deg}: {lateral} {vertical}");
        // the covariance seen along the car's axes
        let axis = |k: usize| rotate(m.core.c(), &rows[k]);
        let var = |k: usize| {
            let e = axis(k);
            (0..3).map(|i| (0..3).map(|j| e[i] * m.core.cov()[VE + i][VE + j] * e[j]).sum::<f64>()).sum::<f64>()
        };
        let s2 = m.p.init_speed_sigma * m.p.init_speed_sigma;
        assert!((var(0) - 0.25).abs() < 1e-9, "turned {yaw_deg}: forward variance {}", var(0));
        assert!((var(1) - s2).abs() < 1e-9, "turned {yaw_deg}: lateral variance {}", var(1));
        assert!((var(2) - s2).abs() < 1e-9, "turned {yaw_deg}: vertical variance {}", var(2));
    }
}
