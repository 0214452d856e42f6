//! The transitions in which a mechanical drive (`[load] mode = "load_law"`, e.g. a pipeline
//! compressor) differs from a generator: no breaker, the PT governed to its minimum governed
//! speed, warmed up there, then ramped in speed to base load; a normal stop ramps it back.
//!
//! Must not hold state of its own: it moves the sequencer's mode (see the module above).

use super::{Mode, Sequencer};
use crate::engine::control::{Loop, Ramp, Series, Setpoint};
use crate::engine::dynamic::Stations;
use crate::engine::load::PtLoad;
use crate::engine::state::Actuator;
use std::sync::Arc;

impl Sequencer {
    /// The transitions in which a mechanical drive differs from a generator (module docs);
    /// `None` for modes it shares with the generator sequence.
    pub(super) fn mechanical_transition(
        &mut self,
        t: f64,
        act: &mut Actuator<'_>,
        st: &Stations,
        law: &PtLoad,
        n2: f64,
    ) -> Option<bool> {
        let q = self.cfg.sequence.clone();
        let n_min = law.speed_for_power_rpm(q.min_load_mw);
        let tol = 1e-6;
        match self.mode {
            Mode::Idle { until } if t >= until - 1e-9 || self.pt_in_governed_range(n2) => {
                // As the generator's PT governor, with the minimum governed speed as the target.
                let r = q.pt_accel_rate_rpm_s;
                let knee = (0.95 * n_min).max(n2).min(n_min);
                let t1 = t + (knee - n2).max(0.0) / r;
                let t2 = t1 + (n_min - knee) / (r / 6.0);
                let series = Series {
                    t_s: vec![t, t1, t2],
                    value: vec![n2.min(knee), knee, n_min],
                };
                let cmd = self.pid(Loop::PtSpeed, Setpoint::Series(Arc::new(series)));
                self.switch_fuel(t, act, st, cmd);
                self.mode = Mode::PtGovern;
            }
            Mode::PtGovern if n2 >= 0.99 * n_min * (1.0 - tol) => {
                // Warm-up at the minimum governed speed, then the speed ramp to base load.
                let n_base = law.speed_for_power_rpm(q.base_load_mw);
                let t1 = t + q.warmup_s;
                let t2 = t1 + (q.base_load_mw - q.min_load_mw) / q.load_ramp_mw_s;
                let series = Series {
                    t_s: vec![t, t1, t2],
                    value: vec![n_min, n_min, n_base],
                };
                let cmd = self.pid(Loop::PtSpeed, Setpoint::Series(Arc::new(series)));
                self.switch_fuel(t, act, st, cmd);
                self.mode = Mode::Loading { ramp_done_at: t2 };
            }
            Mode::Unloading { ramp_done_at } if t >= ramp_done_at - 1e-9 => {
                let cmd = self.pid(Loop::PtSpeed, Setpoint::Ramp(Ramp::hold(n_min)));
                self.switch_fuel(t, act, st, cmd);
                self.mode = Mode::Cooldown {
                    until: t + q.cooldown_s,
                };
            }
            Mode::Idle { .. } | Mode::PtGovern | Mode::Unloading { .. } => return Some(false),
            _ => return None,
        }
        Some(true)
    }

    /// Normal stop of a mechanical drive: the PT speed set-point ramps down to the minimum
    /// governed speed at the loading ramp's speed rate.
    pub(super) fn mechanical_stop(&mut self, t: f64, act: &mut Actuator<'_>, st: &Stations) {
        let Some(law) = self.pt_load.clone() else {
            return;
        };
        let q = &self.cfg.sequence;
        let n_min = law.speed_for_power_rpm(q.min_load_mw);
        let n_base = law.speed_for_power_rpm(q.base_load_mw);
        let rate = (n_base - n_min) * q.load_ramp_mw_s / (q.base_load_mw - q.min_load_mw).max(1e-9);
        let ramp = Ramp {
            t0: t,
            v0: st.n2_rpm,
            rate: rate.max(1.0),
            target: n_min.min(st.n2_rpm),
        };
        let cmd = self.pid(Loop::PtSpeed, Setpoint::Ramp(ramp));
        self.switch_fuel(t, act, st, cmd);
        self.mode = Mode::Unloading {
            ramp_done_at: ramp.end_time().max(t + 1.0),
        };
    }
}
