//! The default filter (`mode = "mekf"`): a multiplicative error-state
//! Kalman filter on a unit quaternion, with the gyro bias and the velocity.
//!
//! # State
//! - attitude `q` (body FRD to navigation NED), its error `dθ` in the
//!   navigation frame: `C_true = (I + [dθ×]) C_est`;
//! - gyro bias `b` (body, rad/s);
//! - velocity `v` of the sensor (NED, m/s);
//! - the wheel-speed scale error `s` (`v_true = (1 + s) v_wheel`; inactive
//!   without a speed source).
//!
//! The gyro drives the attitude, the accelerometer drives the velocity
//! (`v' = C f + g`). Gravity is never *assumed* from the accelerometer:
//! tilt is observed through what the velocity must do, so a sustained
//! acceleration is integrated into the velocity instead of being read as a
//! tilt. The velocity is observed by
//! - standstill: at rest the velocity is zero (ZUPT) and the gyro reads the
//!   bias on all three axes (zero-rate update) — the strongest bias
//!   information a vehicle gets, and what re-anchors everything at a stop;
//! - the ground-vehicle constraint: no lateral and no vertical velocity at
//!   the rear axle (`[mounting] lever_arm` from there to the sensor);
//! - the wheel speed, when configured (`[speed]`);
//! - heading from the magnetometer (only `dθ_z` and the bias are corrected,
//!   never the tilt; gated by a disturbance test on the field's norm and dip).
//!
//! # Costs
//! The state is propagated every sample (quaternion, velocity); the 10x10
//! covariance and the measurement updates run at `update_hz` (default
//! 25 Hz) with the transition accumulated exactly over the samples between
//! (`Φ_θb = -Σ C dt`, `Φ_vθ = -[Σ C f dt ×]`). No allocation.
//!
//! # Policy on top (the paper's structure)
//! Updates correct the attitude and velocity whenever they pass their
//! innovation gate; the bias is learned only when the data say quasi-static:
//! at rest, or with |a|/g0 inside the inner band, the acceleration-change
//! criterion quiet, the turn rate low, for `dwell_s`. A gate that refuses
//! at rest for `relevel_s` is a re-levelling (flagged), never a lock-out;
//! a diverged state (a bias beyond the part's range before a standstill has
//! read it, or velocity constraints refused most of the time) restarts from
//! the prior (flagged, counted).

pub mod aid;
mod context;
mod core;
mod forward_axis;
mod gravity_lp;
mod kalman;
mod params;
mod rules;
mod supervise;
mod tick;
use context::{FieldWatch, GravityWatch};
use core::{Core, ProcessNoise};

use aid::{tilt_innovation, FreeGravity, HeadingAid, LevelWindow, VelocityRefusals, WheelSpeed};
pub use aid::{Aid, AidCounts, AidReport, AidStatus, AidWord, Rows, Why};
use forward_axis::{PullAways, VehicleAxes};
use gravity_lp::{GravityLp, LpGains};
pub use params::{MagUse, MekfParams, Vehicle};
pub use rules::{Rule, RuleCounts, RulesOff};

use super::quat::{self, cross, norm, rotate, rotate_t, Mat3, Quat};
use super::rest::{GravityRef, RestDetector, RestState};
use super::{flags, StepIn};
use crate::estimator::ekf::wrap_pi;
use crate::estimator::switching::{Band, Decision, Switching};

pub const N: usize = 10;
const TH: usize = 0;
const BI: usize = 3;
const VE: usize = 6;
const SC: usize = 9;
/// Within a tick, an RMS vibration about the mean beyond this (g) is a
/// knock, not a car body's ride (the comma2k19 car's is 0.08 g): its
/// integral is no change of the car's speed, and the velocity's noise
/// rises with it (`velocity_noise`).
const SHOCK_G: f64 = 0.5;
/// Standard gravity, m/s^2 per g.
pub const G: f64 = 9.80665;
const D2R: f64 = std::f64::consts::PI / 180.0;
/// A bias estimate further than this many prior sigmas (the part's turn-on
/// range) from the prior is not a bias but a diverged filter: it restarts.
const BIAS_LIMIT_SIGMAS: f64 = 4.0;
/// Seconds of refused heading updates (field not disturbed) after which
/// the heading is opened to what the field says.
const HEADING_REACQUIRE_S: f64 = 5.0;
/// A free unit's bounded velocity moves the heading only while the
/// heading's 1-sigma is within this (rad).
const FREE_HEADING_SIGMA: f64 = 5.0 * D2R;
/// A unit that is not a vehicle, powered on in motion (no standstill has
/// read its bias): once its low-passed gravity has been taken without a
/// break for `accel_tau_s` (the low-pass's own time; it starts as the mean
/// of the samples so far), its tilt has settled on it and a steady residual
/// is the bias's, learned in motion from then on (provisionally, until a
/// standstill reads it, the gravity's lag in the model) with the bias's
/// 1-sigma first brought down to this (rad/s; VQF's
/// motion bias sigma, 0.1 deg/s): the prior's, 3 deg/s, let the lag of
/// the low-passed gravity in a hand's motion run the bias away.
const PROVISIONAL_BIAS_SIGMA: f64 = 0.1 * D2R;
/// Moving, the share of the time (low-passed over `LOST_TAU_S`) the gate
/// refuses the velocity constraints beyond which the filter is lost (its
/// attitude, not the vehicle, is wrong): it restarts from its prior.
const LOST_SHARE: f64 = 0.8;
const LOST_TAU_S: f64 = 5.0;
/// Wheel speeds below this (m/s) are a standing car; with wheel speeds a
/// car is never still while its wheels read more.
const WHEEL_STANDING: f64 = 0.05;
/// The wheels must have read standing this long (s) before a quiet IMU is
/// a standstill without the detector's `min_s`: in the last tenths of a
/// second of a stop the wheels (20-80 ms late) read under `WHEEL_STANDING`
/// while the car still decelerates at 0.05 g, whose |f| is within the rest
/// band of gravity (3 deg of pitch taken for tilt).
const WHEEL_STANDING_S: f64 = 0.5;
/// A counter gap (`resync`): what the unit may have done over it. The
/// attitude opens by `GAP_ATT_BASE` plus `GAP_TURN_RATE` per second of gap
/// (at most a quarter turn), a vehicle's tilt by at most `GAP_VEHICLE_TILT`;
/// the speed by `GAP_SPEED_VAR` plus `GAP_ACCEL` per second of gap.
const GAP_ATT_BASE: f64 = 5.0 * D2R;
const GAP_TURN_RATE: f64 = 30.0 * D2R;
const GAP_VEHICLE_TILT: f64 = 5.0 * D2R;
const GAP_SPEED_VAR: f64 = 4.0;
const GAP_ACCEL: f64 = 3.0;
/// A still period whose specific force lies this far (g) off gravity, along
/// the centripetal acceleration of the filter's own motion, is a turn, not a
/// standstill (`turning_at_speed`): 1.1 deg of tilt, above a rest's tilt
/// noise.
const TURNING_AT_SPEED_G: f64 = 0.02;
/// A car whose magnetic field turns by more than this (deg) in its own frame
/// since the rest detector's conditions began to hold is turning, not
/// standing (`field_turned`): under a 60-deg dip a 3-deg turn of the car
/// (its horizontal half turns), 2 s of a 1.5-deg/s turn, within the 2.5 s
/// to a re-level. The simulated magnetometer (0.5 mgauss per sample) keeps
/// a tick's mean field steady to 0.03 deg.
const FIELD_TURN_DEG: f64 = 1.5;
/// A car whose gravity turns in its own frame by more than this (deg)
/// within `GRAVITY_TURN_WINDOW_S` of a quiet period is moving
/// (`gravity_turned`): a standing car does not pitch or roll, a car
/// rolling over a change of grade does, at its speed times the road's
/// vertical curvature (0.05 deg/s and more at walking pace). A tick's mean
/// specific force, low-passed over 1 s, holds its direction to about 0.1
/// deg at a quiet rest; the rest detector's own drift bound (`drift_g`
/// 0.01 g) is 0.57 deg.
const GRAVITY_TURN_DEG: f64 = 0.5;
const GRAVITY_TURN_WINDOW_S: f64 = 10.0;
/// 1-sigma of the vertical-speed bound (`max_vertical_speed`), m/s.
const VERTICAL_BOUND_SIGMA: f64 = 0.5;
/// A car's body cannot keep rolling or pitching (`fuse_level_rate`): its
/// rate about the horizontal, averaged over `LEVEL_WINDOW_S`, is zero within
/// `LEVEL_RATE_SIGMA` (a grade or a suspension's change over the window:
/// 3 deg in 3 s is a hard braking's dive), on windows turning less than
/// `LEVEL_TURN_MAX` about the vertical.
const LEVEL_WINDOW_S: f64 = 3.0;
const LEVEL_RATE_SIGMA: f64 = 1.0 * D2R;
const LEVEL_TURN_MAX: f64 = 3.0 * D2R;
/// A car's roll, per level window, is zero within this (`fuse_level_roll`).
const LEVEL_ROLL_SIGMA: f64 = 3.0 * D2R;

/// Which gain rows an update may move (the velocity and the speed scale
/// are always in the gain), and whether the power-on bank scores it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Gain {
    /// The tilt (dθ_x, dθ_y).
    tilt: bool,
    /// The heading (dθ_z).
    heading: bool,
    bias: bool,
    /// Scored for the power-on speed hypotheses (`super::hypotheses`)
    /// while scoring: only a measurement every copy of the bank makes
    /// alike (the velocity constraints and the wheel speed), so that their
    /// likelihoods compare the copies' predictions, not which measurements
    /// each happened to make.
    scored: bool,
}

/// Per-tick sums.
#[derive(Clone, Debug, Default)]
struct Accum {
    n: u32,
    t: f64,
    /// Σ C dt and Σ C f dt (f in m/s^2).
    s_c: Mat3,
    /// Σ C ω dt, ω the raw gyro (rad/s): the navigation frame's raw turn
    /// (only while `learns_level_rate`).
    s_cg: [f64; 3],
    dv: [f64; 3],
    /// Σ raw gyro (rad/s), Σ bias-corrected gyro, Σ magnetometer.
    gyro: [f64; 3],
    omega: [f64; 3],
    magn: [f64; 3],
    accel: [f64; 3],
    /// Σ |accelerometer|^2, g^2 (the tick's vibration, `propagate`).
    accel2: f64,
    /// Σ |omega| dt, rad.
    turned: f64,
    /// Σ |turn rate about the vertical| dt, rad.
    turned_z: f64,
    suspect: bool,
    /// The policy held for every sample of the tick.
    quasi: bool,
    rest: bool,
    /// The rest detector's instantaneous conditions held (not yet `min_s`).
    quiet: bool,
}

/// What the updates of one tick did.
#[derive(Clone, Copy, Debug, Default)]
struct Outcome {
    fused: bool,
    learned: bool,
    refused: bool,
    /// The zero-rate update was fused on every axis.
    bias_read: bool,
}

/// Counters the filter keeps for the summary and the status.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct MekfCounters {
    pub relevels: u64,
    pub rest_s: f64,
    pub gated_s: f64,
    pub mag_disturbed_s: f64,
    /// Longest continuous time the velocity constraints were refused, s.
    pub refused_max_s: f64,
    pub speed_used_s: f64,
    /// Times the velocity was widened after its constraints were refused for long.
    pub reacquired: u64,
    /// Times the filter restarted from its prior because its bias left the
    /// range the part allows (a diverged state, never a real bias).
    pub restarts: u64,
    /// Times the vehicle constraint's axes were turned to the way the car
    /// pulls away (`forward_axis`: a unit turned about the vertical).
    pub reaxed: u64,
    /// The rest detector's quietest moments over the run (None before a
    /// sample): what the summary shows when no standstill was ever found.
    /// Filled by `Mekf::counters`.
    pub quietest: Option<Quietest>,
    /// How often each named rule acted (`rules.rs`).
    pub rules: RuleCounts,
    /// At how many ticks each aid source was fused and refused (`aid`).
    pub aid: AidCounts,
}

impl MekfCounters {
    /// No standstill found, and the detector's quietest deviations were at
    /// or above a threshold: the summary and the status say so.
    pub fn rest_never_found(&self) -> Option<Quietest> {
        self.quietest.filter(|q| self.rest_s == 0.0 && (q.gyro_dps >= q.gyro_max_dps || q.accel_g >= q.accel_max_g))
    }
}

/// The smallest RMS deviations the rest detector saw (each on its own, over
/// the run) and its thresholds: a unit that stood still and was never found
/// standing has its noise or vibration above them (a noisier part than the
/// thresholds' ADIS16448, seen in blocks of about 204.8 Hz: `[rest]` needs
/// its own).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Quietest {
    /// Gyro, deg/s over three axes, and `[rest] gyro_dev_dps`.
    pub gyro_dps: f64,
    pub gyro_max_dps: f64,
    /// Specific force, g over three axes, and `[rest] accel_dev_g`.
    pub accel_g: f64,
    pub accel_max_g: f64,
}

impl std::fmt::Display for Quietest {
    /// "gyro 0.72 deg/s ([rest] gyro_dev_dps 0.60) and specific force 0.012 g
    /// (accel_dev_g 0.050)": the replay summary and the daemon's status.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "gyro {:.2} deg/s ([rest] gyro_dev_dps {:.2}) and specific force {:.3} g (accel_dev_g {:.3})",
            self.gyro_dps, self.gyro_max_dps, self.accel_g, self.accel_max_g
        )
    }
}

#[derive(Clone, Debug)]
pub struct Mekf {
    p: MekfParams,
    started: bool,
    /// State and covariance (`core`).
    core: Core,
    /// Low-passed specific force in the navigation frame, g, and the
    /// motion band's mean square (None until started).
    f_lp: Option<GravityLp>,
    /// The attitude low-passed over `accel_tau_s` (per tick, turned with
    /// every correction): what turns a bias error into the low-passed
    /// gravity's lag (`fuse_free_gravity`).
    c_lag: Mat3,
    level: LevelWindow,
    /// The car's axes in the body frame, and the pull-aways that turn them
    /// (`forward_axis`).
    axes: VehicleAxes,
    pulls: PullAways,
    acc: Accum,
    rest: RestDetector,
    /// Gravity's size as this unit measures it, for the rest detector.
    g_ref: GravityRef,
    /// The bias prior at start (rad/s) and its 1-sigma.
    prior: ([f64; 3], [f64; 3]),
    /// Low-passed body-frame specific force and roll/pitch rate power, for
    /// deciding from the measurements alone whether this is a vehicle.
    body_f_lp: [f64; 3],
    last_rest: Option<RestState>,
    switching: Switching,
    dwell: f64,
    /// Magnetometer: decided use (None while undecided), the auto
    /// decision's sums.
    mag_on: Option<bool>,
    mag_sum: f64,
    mag_n: u32,
    /// Seconds still with an update refused; seconds in motion with the
    /// velocity constraints refused.
    refused_still: f64,
    /// The magnetic field (body frame, mean of a tick) when the rest
    /// detector's conditions began to hold (`field_turned`).
    quiet_field: FieldWatch,
    /// The gravity's turn in the body frame over a quiet period
    /// (`gravity_turned`).
    quiet_gravity: GravityWatch,
    /// The aid sources' own states: the velocity constraints' refusals,
    /// the free unit's gravity, the heading, the wheels.
    refusals: VelocityRefusals,
    free_gravity: FreeGravity,
    heading: HeadingAid,
    wheel: WheelSpeed,
    /// What every aid source did at this tick (`aid`), and at the last
    /// finished one (what is published).
    aid: AidReport,
    last_aid: AidReport,
    /// `last_aid` packed as every estimate carries it (packed once a tick).
    last_aid_word: AidWord,
    /// Not a vehicle, no bias read yet: the tilt has settled on the
    /// low-passed gravity since the last start or re-level (the field's
    /// dip re-taken, the bias learned in motion provisionally).
    tilt_settled: bool,
    /// Since the last standstill: ∫ 2|sin(Δψ/2)| dt, s, Δψ the heading
    /// turned since (`velocity_belief`), and the heading there.
    turn_exposure: f64,
    yaw_at_stop: Option<f64>,
    /// A quiet period began after the last counter gap (`after_gap`).
    quiet_since_gap: bool,
    /// A counter gap happened and no quiet period has ended since.
    after_gap: bool,
    /// The bias-corrected rate of the last sample (rad/s), and whether the
    /// velocity still holds the lever arm's turn from before a gap.
    last_w: [f64; 3],
    lever_pending: bool,
    /// A bias is known (a rest was seen or a prior given).
    bias_known: bool,
    /// A standstill has fused gravity with the bias read since the tilt was
    /// last in doubt (start, restart, counter gap): the tilt is held by the
    /// gyro from a tilt the data confirmed (`accelerating`).
    tilt_anchored: bool,
    /// The vehicle model is in use; the x/y body rates' 3-s mean (rad/s)
    /// and the 3-s low-pass of their squared deviation from it.
    vehicle: bool,
    xy_rate_mean: [f64; 2],
    xy_rate2: f64,
    /// The bias sigma as of the last update (the covariance changes only there).
    bias_sigma_cache: [f64; 3],
    /// Low-pass gains for the step length `alpha_dt`.
    alpha_dt: f64,
    lp_gains: LpGains,
    alpha_1s: f64,
    /// The last tick's outcome, held until the next tick.
    mode: u8,
    tick_flags: u16,
    /// Bias and temperature of the last tick that learned the bias.
    last_learned: Option<(f64, [f64; 3])>,
    /// A learning point for the thermal slope: (temp, bias deg/s, weight s).
    rest_point: Option<(f64, [f64; 3], f64)>,
    pub(in crate::estimator) counters: MekfCounters,
    /// The rest detector's smallest mean square deviations over the run
    /// (gyro (rad/s)^2, specific force g^2; `Mekf::counters` reports them).
    quietest_var: Option<[f64; 2]>,
    /// What the last `step` returned (mode, flags, ratio).
    last_step: (u8, u16, f64),
}

impl Mekf {
    pub fn new(p: MekfParams, switching: Switching) -> Mekf {
        let rest = RestDetector::new(p.rest);
        let axes = VehicleAxes::new(0.0, p.lever);
        let core = Core::new(p.speed_aided);
        Mekf {
            p,
            started: false,
            core,
            f_lp: None,
            c_lag: quat::to_matrix(&[1.0, 0.0, 0.0, 0.0]),
            level: LevelWindow::default(),
            axes,
            pulls: PullAways::default(),
            acc: Accum::default(),
            rest,
            last_rest: None,
            switching,
            dwell: 0.0,
            mag_on: None,
            mag_sum: 0.0,
            mag_n: 0,
            refused_still: 0.0,
            quiet_field: FieldWatch::default(),
            quiet_gravity: GravityWatch::default(),
            refusals: VelocityRefusals::default(),
            free_gravity: FreeGravity::default(),
            heading: HeadingAid::default(),
            wheel: WheelSpeed::default(),
            aid: AidReport::default(),
            last_aid: AidReport::default(),
            last_aid_word: AidWord::default(),
            tilt_settled: false,
            turn_exposure: 0.0,
            yaw_at_stop: None,
            quiet_since_gap: false,
            after_gap: false,
            last_w: [0.0; 3],
            lever_pending: false,
            bias_known: false,
            tilt_anchored: false,
            vehicle: true,
            xy_rate_mean: [0.0; 2],
            xy_rate2: 0.0,
            g_ref: GravityRef::default(),
            prior: ([0.0; 3], [0.0; 3]),
            body_f_lp: [0.0, 0.0, -1.0],
            bias_sigma_cache: [0.0; 3],
            alpha_dt: -1.0,
            lp_gains: LpGains::new(1.0, 1.0),
            alpha_1s: 0.0,
            mode: 2,
            tick_flags: 0,
            last_learned: None,
            rest_point: None,
            counters: MekfCounters::default(),
            quietest_var: None,
            last_step: (2, 0, 1.0),
        }
    }

    /// Start on the first sample: tilt from the accelerometer, heading from
    /// the magnetometer when it is plausible, the bias given (rad/s) with its
    /// sigma, the velocity zero with `init_speed_sigma`.
    pub fn start(&mut self, accel: &[f64; 3], magn: &[f64; 3], bias: [f64; 3], bias_sigma: [f64; 3], known: bool) {
        let (roll, pitch) = crate::estimator::ekf::tilt_from_accel(accel);
        let mut yaw = 0.0;
        let mn = norm(magn);
        if self.p.mag != MagUse::Off && mn > 0.1 && mn < 1.0 {
            yaw = wrap_pi(crate::estimator::ekf::heading_from_mag(magn, roll, pitch) + self.p.declination);
        }
        self.prior = (bias, bias_sigma);
        self.body_f_lp = *accel;
        self.f_lp = None;
        self.initialise([roll, pitch, yaw], bias, bias_sigma);
        self.c_lag = *self.core.c();
        self.bias_known = known;
        self.bias_sigma_cache = self.bias_sigma();
        // with the car's own speed it is a vehicle
        self.vehicle = self.p.vehicle != Vehicle::Off || self.p.speed_aided;
        self.xy_rate_mean = [0.0; 2];
        self.xy_rate2 = 0.0;
        self.acc = Accum { quasi: true, rest: true, quiet: true, ..Accum::default() };
        self.rest.reset();
        self.switching.reset();
        self.dwell = 0.0;
        self.mode = 2;
        self.tick_flags = 0;
        self.started = true;
    }

    /// A power-on hypothesis of the forward speed (m/s, along the vehicle's
    /// x axis) with its 1-sigma; the lateral and vertical velocity keep
    /// `init_speed_sigma`. Call right after `start`; starts scoring.
    pub fn set_speed_hypothesis(&mut self, u: f64, sigma: f64) {
        // the car's axes in the navigation frame: E = C A^T, column k the
        // car's axis k (A's row k, in the body) turned by the attitude
        let e: [[f64; 3]; 3] = std::array::from_fn(|k| rotate(self.core.c(), &self.axes.rows[k]));
        self.core.set_velocity(e[0].map(|x| x * u));
        let s2 = self.p.init_speed_sigma * self.p.init_speed_sigma;
        let d = [sigma * sigma, s2, s2];
        // E diag(d) E^T: the forward speed's variance along the car's x axis
        let m: Mat3 = std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| e[k][i] * d[k] * e[k][j]).sum()));
        self.core.set_velocity_cov(&m);
        self.set_scoring(true);
    }

    /// Start or stop accumulating the log-likelihood (see `log_likelihood`).
    pub fn set_scoring(&mut self, on: bool) {
        self.core.set_scoring(on);
    }

    /// The log-likelihood of the measurements since scoring started.
    pub fn log_likelihood(&self) -> f64 {
        self.core.log_likelihood()
    }

    /// The bias, rad/s.
    pub fn bias(&self) -> [f64; 3] {
        *self.core.bias()
    }

    /// The temperature (deg C) and bias (deg/s) of the last tick that
    /// learned the bias.
    pub fn last_learned(&self) -> Option<(f64, [f64; 3])> {
        self.last_learned
    }

    /// The thermal slope's learning point of the last tick, once: (temp,
    /// bias deg/s, weight s), at a standstill.
    pub fn take_rest_point(&mut self) -> Option<(f64, [f64; 3], f64)> {
        self.rest_point.take()
    }

    /// What every aid source did at the last update tick.
    pub fn aid_report(&self) -> &AidReport {
        &self.last_aid
    }

    /// The last update tick's aid report as an estimate carries it.
    pub fn aid_word(&self) -> AidWord {
        self.last_aid_word
    }

    /// What the last `step` returned.
    pub fn last_step(&self) -> (u8, u16, f64) {
        self.last_step
    }

    /// Whether the named situation rule is on (all are, unless switched off
    /// for ablation: `[mekf] ablate`).
    #[inline]
    pub fn on(&self, r: Rule) -> bool {
        self.p.off.on(r)
    }

    /// Whether the vehicle's speed is configured as a measurement.
    pub fn speed_aided(&self) -> bool {
        self.p.speed_aided
    }

    pub fn started(&self) -> bool {
        self.started
    }

    /// Attitude as Z-Y-X Euler angles, rad.
    pub fn euler(&self) -> [f64; 3] {
        quat::euler(self.core.c())
    }

    pub fn quaternion(&self) -> Quat {
        *self.core.q()
    }

    /// 1-sigma of the bias, rad/s.
    pub fn bias_sigma(&self) -> [f64; 3] {
        [
            self.core.cov()[BI][BI].max(0.0).sqrt(),
            self.core.cov()[BI + 1][BI + 1].max(0.0).sqrt(),
            self.core.cov()[BI + 2][BI + 2].max(0.0).sqrt(),
        ]
    }

    /// Velocity (NED, m/s).
    pub fn velocity(&self) -> [f64; 3] {
        *self.core.v()
    }

    /// The counters, with the rest detector's quietest deviations against
    /// its thresholds.
    pub fn counters(&self) -> MekfCounters {
        let rp = &self.p.rest;
        let quietest = self.quietest_var.map(|[g, a]| Quietest {
            gyro_dps: g.sqrt() / D2R,
            gyro_max_dps: rp.gyro_dev / D2R,
            accel_g: a.sqrt(),
            accel_max_g: rp.accel_dev,
        });
        MekfCounters { quietest, ..self.counters }
    }

    /// Forward speed at the rear axle, m/s.
    pub fn forward_speed(&self) -> f64 {
        let vb = rotate_t(self.core.c(), self.core.v());
        let x = self.axes.rows[0];
        x[0] * vb[0] + x[1] * vb[1] + x[2] * vb[2]
    }

    /// The wheel-speed scale error estimate.
    pub fn speed_scale(&self) -> f64 {
        self.core.scale()
    }

    /// Whether the vehicle model is in use.
    pub fn vehicle(&self) -> bool {
        self.vehicle
    }

    /// Whether the magnetometer is used (None: not decided yet).
    pub fn magnetometer(&self) -> Option<bool> {
        self.mag_on
    }

    /// The standstill detector's last state (for diagnostics).
    pub fn rest_state(&self) -> Option<RestState> {
        self.last_rest
    }

    /// The covariance (for tests).
    pub fn covariance(&self) -> &[[f64; N]; N] {
        self.core.cov()
    }

    /// The latest wheel speed (m/s) while fresh, None when stale or absent;
    /// `new` when it arrived since the previous sample (each frame is fused
    /// once).
    pub fn set_speed(&mut self, v: Option<f64>, new: bool) {
        self.wheel.set(v, new);
    }

    fn state_is_finite(&self) -> bool {
        self.core.is_finite()
    }

    /// One sample; returns (mode, flags, `|a| / g0` as the switching policy
    /// read it).
    pub fn step(&mut self, s: &StepIn) -> (u8, u16, f64) {
        let gyro = [s.gyro[0] * D2R, s.gyro[1] * D2R, s.gyro[2] * D2R];
        let w = self.corrected_rate(&gyro, &s.dbias);
        let wn = norm(&w);
        self.set_step_length(s.dt);
        if s.dt > 0.0 {
            self.propagate_sample(s, &gyro, &w, wn);
        }
        self.decide_magnetometer(s);
        // Policy: the paper's switching, the turn rate, the dwell.
        let dec = self.switching.classify(&s.accel, s.g0);
        let rest = self.push_rest(s, &gyro);
        self.accumulate_sample(s, &gyro, &w, wn, &dec, rest);
        let mut fl = 0u16;
        if dec.jerk {
            fl |= flags::JERK;
        }
        fl |= self.tick_when_due(s.temp);
        self.last_step = (self.mode, fl | self.tick_flags, dec.ratio);
        self.last_step
    }

    /// The bias-corrected rate of this sample (rad/s; `gyro` raw, rad/s),
    /// with the thermal curve's change since the previous sample (`dbias`,
    /// deg/s) moved into the bias first. The first sample after a counter
    /// gap also turns the velocity's lever-arm part to the rate now.
    fn corrected_rate(&mut self, gyro: &[f64; 3], dbias: &[f64; 3]) -> [f64; 3] {
        self.core.add_bias(&[dbias[0] * D2R, dbias[1] * D2R, dbias[2] * D2R]);
        let w = [gyro[0] - self.core.bias()[0], gyro[1] - self.core.bias()[1], gyro[2] - self.core.bias()[2]];
        if self.lever_pending {
            // The velocity is the sensor's: it holds the lever arm's turn
            // (ω × l) at the rate before the gap. Turn it to the rate now.
            let dw = [w[0] - self.last_w[0], w[1] - self.last_w[1], w[2] - self.last_w[2]];
            let d = rotate(self.core.c(), &cross(&dw, &self.axes.lever));
            self.core.add_velocity(&d);
            self.lever_pending = false;
        }
        self.last_w = w;
        w
    }

    /// The low-pass gains for this step length (s): computed again only
    /// when it changes, which a constant sample rate does only after gaps.
    fn set_step_length(&mut self, dt: f64) {
        if dt != self.alpha_dt {
            self.alpha_dt = dt;
            self.lp_gains = LpGains::new(dt, self.p.accel_tau);
            self.alpha_1s = dt.min(1.0);
        }
    }

    /// Propagate the state over one sample (`dt > 0`): the attitude by the
    /// bias-corrected rate `w`, the velocity by the specific force turned
    /// into the navigation frame plus gravity, the low-passed gravity, and
    /// the tick's sums from which the covariance's transition is built
    /// exactly (`Φ_θb = -Σ C dt`, `Φ_vθ = -[Σ C f dt ×]`). `gyro` is the raw
    /// rate (rad/s) the level-rate window and the motion model read.
    fn propagate_sample(&mut self, s: &StepIn, gyro: &[f64; 3], w: &[f64; 3], wn: f64) {
        let dt = s.dt;
        self.core.integrate_attitude(w, dt);
        let f = rotate(self.core.c(), &s.accel);
        match self.f_lp.as_mut() {
            None => self.f_lp = Some(GravityLp::new(&f, &self.lp_gains)),
            Some(lp) => lp.push(&f, &self.lp_gains),
        }
        // v' = (C f + e_z) g0 G: g0 is the unit's reading of 1 g. At rest
        // this leaves g0 (1 - |f|) G, a few hundredths of m/s^2 that the
        // zero-velocity update absorbs. The alternatives (standard
        // gravity; f scaled by the rests' |f|) were measured on the
        // simulator and the real recordings: none better beyond noise.
        let gl = s.g0 * G;
        let g_nav = if self.learns_level_rate() { rotate(self.core.c(), gyro) } else { [0.0; 3] };
        self.core.integrate_velocity(&f, gl, dt);
        let a = &mut self.acc;
        for i in 0..3 {
            for j in 0..3 {
                a.s_c[i][j] += self.core.c()[i][j] * dt;
            }
            a.s_cg[i] += g_nav[i] * dt;
            a.dv[i] += f[i] * gl * dt;
        }
        a.t += dt;
        a.turned += wn * dt;
        // the turn about the vertical: the heading's share of a scale error
        let wz = self.core.c()[2][0] * w[0] + self.core.c()[2][1] * w[1] + self.core.c()[2][2] * w[2];
        a.turned_z += wz.abs() * dt;
        self.watch_vehicle_model(gyro, &s.accel);
    }

    /// The magnetometer decision, once: as configured, or (auto) whether the
    /// mean |m| over the g0 window is an Earth field (0.1-1 gauss) rather
    /// than a dead or saturated sensor.
    fn decide_magnetometer(&mut self, s: &StepIn) {
        if self.mag_on.is_some() {
            return;
        }
        match self.p.mag {
            MagUse::On => self.mag_on = Some(true),
            MagUse::Off => self.mag_on = Some(false),
            MagUse::Auto => {
                self.mag_sum += norm(&s.magn);
                self.mag_n += 1;
                if s.t >= self.p.g0_window_s {
                    let m = self.mag_sum / self.mag_n as f64;
                    self.mag_on = Some(m > 0.1 && m < 1.0);
                }
            }
        }
    }

    /// The standstill detector on this sample (`gyro` raw, rad/s); a
    /// suspect sample resets it and gives None. What it says also tells
    /// whether g0 is gravity.
    fn push_rest(&mut self, s: &StepIn, gyro: &[f64; 3]) -> Option<RestState> {
        let dt = s.dt;
        // Before the first standstill any steady rate may be the bias: the
        // first rest after power-on initialises it, whatever its size.
        let bs = if self.bias_known { self.bias_sigma_cache } else { [f64::INFINITY; 3] };
        let rest = if s.suspect {
            self.rest.reset();
            None
        } else {
            Some(self.rest.push(gyro, &s.accel, dt.max(1e-6), self.g_ref.get(), self.core.bias(), bs))
        };
        // g0 is gravity only if the unit was steady while it was measured
        // (powered on while driving, it holds the car's acceleration); then
        // |f| at the rests
        self.g_ref.observe(rest.as_ref(), s.t, s.g0, self.p.g0_window_s, dt);
        rest
    }

    /// Add the sample to the tick's sums, with what the policy says of it:
    /// quasi-static (at rest, or quiet for `dwell_s`: inside the inner band,
    /// no jerk, no turn, not suspect), at rest, quiet; and keep the rest
    /// detector's last state and quietest deviations.
    fn accumulate_sample(&mut self, s: &StepIn, gyro: &[f64; 3], w: &[f64; 3], wn: f64, dec: &Decision, rest: Option<RestState>) {
        let dt = s.dt;
        let at_rest = rest.is_some_and(|r| r.rest);
        let turn = wn > self.p.turn_rate;
        let quiet = dec.band == Band::Inner && !dec.jerk && !turn && !s.suspect;
        self.dwell = if quiet { self.dwell + dt } else { 0.0 };
        let a = &mut self.acc;
        a.n += 1;
        for i in 0..3 {
            a.gyro[i] += gyro[i];
            a.omega[i] += w[i];
            a.magn[i] += s.magn[i];
            a.accel[i] += s.accel[i];
        }
        a.accel2 += s.accel[0] * s.accel[0] + s.accel[1] * s.accel[1] + s.accel[2] * s.accel[2];
        a.suspect |= s.suspect;
        a.quasi &= at_rest || self.dwell >= self.p.dwell_s;
        a.rest &= at_rest;
        a.quiet &= rest.is_some_and(|r| r.quiet);
        if let Some(r) = &rest {
            self.last_rest = rest;
            let q = self.quietest_var.get_or_insert([r.gyro_var, r.accel_var]);
            q[0] = q[0].min(r.gyro_var);
            q[1] = q[1].min(r.accel_var);
        }
    }

    /// The update tick once `tick_s` of samples are summed. A state gone
    /// non-finite stops the filter (returns `RESYNC`): it cannot happen
    /// with finite input, and a NaN must never get out.
    fn tick_when_due(&mut self, temp: f64) -> u16 {
        if self.acc.t + 1e-9 >= self.p.tick_s {
            self.tick(temp);
            self.bias_sigma_cache = self.bias_sigma();
            if !self.state_is_finite() {
                self.started = false;
                return flags::RESYNC;
            }
        } else if !self.core.q()[0].is_finite() {
            self.started = false;
            return flags::RESYNC;
        }
        0
    }

    /// The state at power-on (and at a restart): the attitude given, the
    /// bias and its sigma, the velocity unknown, no speed scale error.
    fn initialise(&mut self, euler: [f64; 3], bias: [f64; 3], bias_sigma: [f64; 3]) {
        self.free_gravity.held_s = 0.0;
        self.tilt_anchored = false;
        self.tilt_settled = false;
        let a = self.p.init_angle_sigma * self.p.init_angle_sigma;
        let mut var = [0.0; N];
        for i in 0..3 {
            var[TH + i] = a;
            var[BI + i] = bias_sigma[i] * bias_sigma[i];
            var[VE + i] = self.p.init_speed_sigma * self.p.init_speed_sigma;
        }
        // heading is far less known than tilt until the magnetometer speaks
        var[TH + 2] = (std::f64::consts::PI / 2.0).powi(2);
        if self.p.speed_aided {
            var[SC] = self.p.init_scale_sigma * self.p.init_scale_sigma;
        }
        self.core.reset(quat::from_euler(euler[0], euler[1], euler[2]), bias, &var);
    }

    fn bias_deg(&self) -> [f64; 3] {
        [self.core.bias()[0] / D2R, self.core.bias()[1] / D2R, self.core.bias()[2] / D2R]
    }
}

#[cfg(test)]
mod tests;
