//! Frames into samples by the plan: equal counters, or a time window.

use super::plan::{Assembly, DbcPlan};
use crate::adis::{Drop, InputCounters, Push, RawFrame, Sample, RESYNC_AFTER};
use std::sync::Arc;

/// The sample in progress and the history the checks need.
#[derive(Clone, Debug, Default)]
struct State {
    /// One bit per message received for the sample in progress, and all of them.
    have: u32,
    full: u32,
    /// Counter of the sample in progress, or the time its window opened (us).
    cur: u64,
    /// Decoded channels of the sample in progress ([`crate::config::dbcin::CHANNELS`] order).
    vals: [f64; 7],
    diag: u16,
    /// Counter (or window time, us) of the last accepted sample.
    last: Option<u64>,
    stale_run: u32,
    /// The running sample counter reported as `Sample::cnt`.
    seq: u16,
}

/// Assembles samples from the frames of a DBC-described IMU. Holds one
/// sample in progress; allocates nothing per frame.
#[derive(Clone, Debug)]
pub struct DbcAssembler {
    plan: Arc<DbcPlan>,
    st: State,
    pub counters: InputCounters,
}

fn drop(c: &mut InputCounters, d: Drop) -> Push {
    c.bump(d);
    Push::Dropped(d)
}

impl DbcAssembler {
    pub fn new(plan: Arc<DbcPlan>) -> DbcAssembler {
        let full = ((1u64 << plan.msgs.len()) - 1) as u32;
        DbcAssembler { plan, st: State { full, ..State::default() }, counters: InputCounters::default() }
    }

    pub fn plan(&self) -> &DbcPlan {
        &self.plan
    }

    /// Push one frame received at `t_us`.
    pub fn push(&mut self, t_us: u64, f: RawFrame<'_>) -> Push {
        let DbcAssembler { plan, st, counters } = self;
        let plan: &DbcPlan = plan;
        counters.frames += 1;
        let Some(mi) = (if f.remote { None } else { plan.find(f.id, f.extended) }) else {
            return drop(counters, Drop::UnknownId);
        };
        let m = &plan.msgs[mi];
        if f.data.len() != m.len {
            return drop(counters, Drop::WrongDlc);
        }
        if m.crc.is_some_and(|c| !c.ok(f.data)) {
            return drop(counters, Drop::Checksum);
        }
        let bit = 1u32 << mi;
        match plan.assembly {
            Assembly::Counter { modulus } => {
                let cnt = m.counter.map_or(0, |c| c.raw(f.data));
                if let Some(d) = st.by_counter(counters, cnt, bit, u64::from(modulus)) {
                    return drop(counters, d);
                }
            }
            Assembly::Window { us } => st.by_window(counters, t_us, bit, us),
        }
        for &k in &m.channels {
            if let Some(c) = &plan.channels[k] {
                st.vals[k] = c.value(f.data);
            }
        }
        for (ex, want, b) in &m.valid {
            if ex.raw(f.data) != *want {
                st.diag |= b;
            }
        }
        st.have |= bit;
        if st.have != st.full {
            return Push::Pending;
        }
        let steps = match (plan.assembly, st.last) {
            (_, None) => 0,
            (Assembly::Counter { modulus }, Some(l)) => ((st.cur + u64::from(modulus) - l) % u64::from(modulus)) as u32,
            // from the time since the last sample's window, at the nominal rate
            (Assembly::Window { .. }, Some(l)) => {
                let dt = st.cur.saturating_sub(l) as f64 * 1e-6;
                (dt * plan.rate_hz).round().clamp(1.0, f64::from(u16::MAX)) as u32
            }
        };
        Push::Sample(st.complete(plan, counters, t_us, steps))
    }
}

impl State {
    /// Counter mode: the checks of the ADIS path modulo the counter's width;
    /// Some: the frame is dropped for that cause.
    fn by_counter(&mut self, c: &mut InputCounters, cnt: u64, bit: u32, m: u64) -> Option<Drop> {
        if let Some(last) = self.last {
            let d = (cnt + m - last) % m;
            if d == 0 {
                return Some(Drop::Duplicate);
            }
            if d >= m / 2 {
                self.stale_run += 1;
                if self.stale_run < RESYNC_AFTER {
                    return Some(Drop::OutOfOrder);
                }
                // a run of "older" frames: the sensor restarted its counter
                c.resyncs += 1;
                self.last = None;
                self.have = 0;
            }
        }
        self.stale_run = 0;
        if self.have != 0 && cnt != self.cur {
            // a newer sample started before this one completed: abandon this one
            self.have = 0;
            c.bump(Drop::Partial);
        }
        if self.have & bit != 0 {
            return Some(Drop::Duplicate);
        }
        if self.have == 0 {
            self.diag = 0;
        }
        self.cur = cnt;
        None
    }

    /// Window mode: a message seen twice, or a frame after the window, abandons the sample.
    fn by_window(&mut self, c: &mut InputCounters, t_us: u64, bit: u32, us: u64) {
        if self.have != 0 && (self.have & bit != 0 || t_us.saturating_sub(self.cur) > us) {
            self.have = 0;
            c.bump(Drop::Partial);
        }
        if self.have == 0 {
            self.cur = t_us;
            self.diag = 0;
        }
    }

    fn complete(&mut self, plan: &DbcPlan, c: &mut InputCounters, t_us: u64, steps: u32) -> Sample {
        self.have = 0;
        if steps > 1 {
            c.gaps += 1;
            c.lost += u64::from(steps - 1);
        }
        self.seq = if self.last.is_none() { 0 } else { self.seq.wrapping_add(steps as u16) };
        self.last = Some(self.cur);
        c.samples += 1;
        let v = &self.vals;
        let s = Sample {
            cnt: self.seq,
            t_us,
            steps,
            gyro: [v[0], v[1], v[2]],
            accel: [v[3], v[4], v[5]],
            magn: [0.0; 3],
            temp: if plan.channels[6].is_some() { v[6] } else { plan.temp_default },
            diag: self.diag,
        };
        if s.suspect() {
            c.suspect += 1;
        }
        s
    }
}
