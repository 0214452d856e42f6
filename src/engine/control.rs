//! Engine control: the fuel controller (PID with back-calculation anti-windup and ratio-unit
//! acceleration/deceleration limits), set-point ramps, and the starter.
//!
//! These are the continuous parts evaluated inside the model's right-hand side; the discrete
//! sequencing (which loop is active, when the starter cuts out) lives in `sequence.rs`.
//! Pure: a command is a value; evaluating it has no side effects.
//! Must not sequence the start (that is `sequence.rs`) or do I/O.

use super::config::{ControlConfig, StarterConfig};
use std::sync::Arc;

/// A linear ramp from `v0` at `t0` towards `target` at `rate` per second (then held).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ramp {
    pub t0: f64,
    pub v0: f64,
    pub rate: f64,
    pub target: f64,
}

impl Ramp {
    pub fn hold(v: f64) -> Ramp {
        Ramp {
            t0: 0.0,
            v0: v,
            rate: 0.0,
            target: v,
        }
    }

    pub fn value(&self, t: f64) -> f64 {
        let dt = (t - self.t0).max(0.0);
        if self.target >= self.v0 {
            (self.v0 + self.rate.abs() * dt).min(self.target)
        } else {
            (self.v0 - self.rate.abs() * dt).max(self.target)
        }
    }

    /// Time at which the ramp reaches its target.
    pub fn end_time(&self) -> f64 {
        if self.rate == 0.0 {
            self.t0
        } else {
            self.t0 + (self.target - self.v0).abs() / self.rate.abs()
        }
    }
}

/// What the fuel controller's loops feed back on: the model's own (true) values of compressor
/// delivery pressure, shaft speeds and PT shaft power.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feedback {
    pub p2_kpa: f64,
    pub n1_rpm: f64,
    pub n2_rpm: f64,
    pub power_mw: f64,
}

impl Feedback {
    /// The feedback values of a station table.
    pub fn of(st: &super::gas_path::Stations) -> Feedback {
        Feedback {
            p2_kpa: st.p2_kpa,
            n1_rpm: st.n1_rpm,
            n2_rpm: st.n2_rpm,
            power_mw: st.pt_shaft_mw,
        }
    }
}

/// Fuel-flow limits: acceleration and deceleration schedules in ratio units (fuel / P2), the
/// flame-holding minimum, and optionally a gas-generator minimum-speed floor.
#[derive(Debug, Clone, PartialEq)]
pub struct FuelLimits {
    accel_speed_rpm: Vec<f64>,
    accel_ratio: Vec<f64>,
    decel_ratio: f64,
    min_fuel: f64,
    gg_floor: Option<GgFloor>,
}

/// A proportional (droop) minimum-speed limit on the gas generator: below `speed_rpm` the fuel's
/// lower limit is `gain · (speed_rpm − n1)`. A limit, not a loop: it is continuous in the state
/// and the governing loop's anti-windup sees it like any other limit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GgFloor {
    pub speed_rpm: f64,
    pub gain_kg_s_per_rpm: f64,
}

impl FuelLimits {
    pub fn from_config(c: &ControlConfig) -> FuelLimits {
        FuelLimits {
            accel_speed_rpm: c.accel_limit_speed_rpm.clone(),
            accel_ratio: c.accel_limit_ratio_kg_s_per_kpa.clone(),
            decel_ratio: c.decel_limit_ratio_kg_s_per_kpa,
            min_fuel: c.min_fuel_kg_s,
            gg_floor: None,
        }
    }

    /// These limits with a gas-generator minimum-speed floor.
    pub fn with_gg_floor(mut self, floor: GgFloor) -> FuelLimits {
        self.gg_floor = Some(floor);
        self
    }

    /// (lower, upper) fuel limit at this speed and compressor delivery pressure.
    pub fn bounds(&self, n1_rpm: f64, p2_kpa: f64) -> (f64, f64) {
        let ru = interp(&self.accel_speed_rpm, &self.accel_ratio, n1_rpm);
        let hi = ru * p2_kpa;
        let floor = self
            .gg_floor
            .map_or(0.0, |f| f.gain_kg_s_per_rpm * (f.speed_rpm - n1_rpm));
        let lo = (self.decel_ratio * p2_kpa)
            .max(self.min_fuel)
            .max(floor)
            .min(hi);
        (lo, hi)
    }
}

/// Piecewise-linear interpolation, held constant outside the table.
pub fn interp(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    if xs.is_empty() {
        return 0.0;
    }
    if x <= xs[0] {
        return ys[0];
    }
    let last = xs.len() - 1;
    if x >= xs[last] || last == 0 {
        return ys[last];
    }
    let i = segment_index(xs, x);
    let f = (x - xs[i]) / (xs[i + 1] - xs[i]);
    ys[i] + f * (ys[i + 1] - ys[i])
}

/// The segment of the sorted `xs` holding `x` (`xs[0] < x < xs[last]`): the largest `i` with
/// `xs[i] <= x`, as `partition_point` finds it. A replay's measured series is read at every
/// right-hand-side evaluation, and a binary search over its hundreds of samples was 6 % of a
/// Method B fit: the index is first guessed from the mean spacing (exact for a uniformly
/// sampled recording) and corrected by a short walk, with the binary search as the fallback.
#[inline]
fn segment_index(xs: &[f64], x: f64) -> usize {
    let last = xs.len() - 1;
    let guess = (x - xs[0]) / (xs[last] - xs[0]) * last as f64;
    // `as` saturates (NaN to 0), so the guess is always an index.
    let mut i = (guess as usize).min(last - 1);
    for _ in 0..4 {
        if xs[i] > x {
            i = i.saturating_sub(1);
        } else if xs[i + 1] <= x && i + 1 < last {
            i += 1;
        } else {
            break;
        }
    }
    if xs[i] <= x && x < xs[i + 1] {
        i
    } else {
        xs.partition_point(|&v| v <= x)
            .saturating_sub(1)
            .min(last - 1)
    }
}

/// Which quantity a closed fuel loop regulates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Loop {
    /// GG speed, rpm.
    GgSpeed,
    /// PT speed, rpm (unloaded PT before synchronisation).
    PtSpeed,
    /// Electrical power, MW.
    Power,
}

/// A measured time series (piecewise linear in time, held outside its span): the fuel flow of an
/// open-loop run, or a set-point that follows the plant.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub t_s: Vec<f64>,
    pub value: Vec<f64>,
}

impl Series {
    pub fn value(&self, t: f64) -> f64 {
        interp(&self.t_s, &self.value, t)
    }

    /// Slope of the piecewise-linear series at `t`, per second (0 outside its span).
    pub fn slope(&self, t: f64) -> f64 {
        let (xs, ys) = (&self.t_s, &self.value);
        if xs.len() < 2 || t < xs[0] || t >= xs[xs.len() - 1] {
            return 0.0;
        }
        let i = segment_index(xs, t);
        (ys[i + 1] - ys[i]) / (xs[i + 1] - xs[i])
    }

    /// The series smoothed by a centred moving average over `window_s`: each value becomes the
    /// plain mean of the samples within half the window either side (same times).
    pub fn smoothed(&self, window_s: f64) -> Series {
        let n = self.t_s.len();
        let mut out = Vec::with_capacity(n);
        let (mut lo, mut hi, mut sum) = (0usize, 0usize, 0.0);
        for i in 0..n {
            let t = self.t_s[i];
            while hi < n && self.t_s[hi] <= t + 0.5 * window_s {
                sum += self.value[hi];
                hi += 1;
            }
            while self.t_s[lo] < t - 0.5 * window_s {
                sum -= self.value[lo];
                lo += 1;
            }
            out.push(sum / (hi - lo) as f64);
        }
        Series {
            t_s: self.t_s.clone(),
            value: out,
        }
    }
}

/// A ramp at `rate` from `v0` at `t0` that blends, with the same slope, into an exponential
/// approach to `target`: `v(t) = target − rate·τ·e^{−(t−t1)/τ}` after the hand-over at `t1`,
/// where the remaining error is `rate·τ`. Continuous in value and slope (a PT governor's
/// set-point: the acceleration the PT is asked for fades out instead of stopping).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Approach {
    t0: f64,
    v0: f64,
    rate: f64,
    t1: f64,
    /// Remaining error at the hand-over, `target − v(t1)` (≥ 0).
    gap: f64,
    target: f64,
}

impl Approach {
    /// From `v0` at `t0` up to `target`: at `rate` (> 0) until `rate·tau` below the target, then
    /// exponentially with time constant `tau` (at once when already closer than that; `tau = 0`:
    /// the plain ramp).
    pub fn new(t0: f64, v0: f64, target: f64, rate: f64, tau: f64) -> Approach {
        let rate = rate.abs().max(1e-9);
        let knee = (target - rate * tau.max(0.0)).max(v0).min(target);
        Approach {
            t0,
            v0,
            rate,
            t1: t0 + (knee - v0).max(0.0) / rate,
            gap: target - knee,
            target,
        }
    }

    /// The first time the set-point reaches `v` (`t0` when it starts above; infinite when `v`
    /// is at or beyond the target, which the exponential never reaches).
    pub fn time_at(&self, v: f64) -> f64 {
        if v <= self.v0 {
            return self.t0;
        }
        let knee = self.target - self.gap;
        if v <= knee {
            return self.t0 + (v - self.v0) / self.rate;
        }
        if v >= self.target {
            return f64::INFINITY;
        }
        let tau = self.gap / self.rate;
        self.t1 - tau * ((self.target - v) / self.gap).ln()
    }

    pub fn value(&self, t: f64) -> f64 {
        if t <= self.t1 {
            return self.v0 + self.rate * (t - self.t0).max(0.0);
        }
        if self.gap <= 0.0 {
            return self.target;
        }
        // The exponential's time constant gives the ramp's slope at the hand-over.
        let tau = self.gap / self.rate;
        self.target - self.gap * (-(t - self.t1) / tau).exp()
    }
}

/// A controller set-point: a ramp, a smooth approach, or a measured series to follow.
#[derive(Debug, Clone, PartialEq)]
pub enum Setpoint {
    Ramp(Ramp),
    Approach(Approach),
    Series(Arc<Series>),
}

impl Setpoint {
    /// The first time after `t` (by more than 1e-9 s) at which the set-point's slope jumps: a
    /// series' next sample, a ramp's start or end. An integrator step across such a kink is
    /// rejected and cut until one straddles it (eight rejections at the start of the load
    /// ramp); a step that ends there costs nothing. An approach bends smoothly: none.
    pub fn next_kink(&self, t: f64) -> Option<f64> {
        match self {
            Setpoint::Ramp(r) => [r.t0, r.end_time()]
                .into_iter()
                .find(|&k| r.rate != 0.0 && k > t + 1e-9),
            Setpoint::Approach(_) => None,
            Setpoint::Series(s) => s.t_s.iter().copied().find(|&k| k > t + 1e-9),
        }
    }

    /// Whether the set-point's slope jumps at `t` (within 1e-9 s).
    pub fn kinks_at(&self, t: f64) -> bool {
        self.next_kink(t - 2e-9).is_some_and(|k| k <= t + 1e-9)
    }

    /// Whether `other` is this set-point: ramps and approaches by value, a followed series by
    /// identity (an equal copy counts as different; cheap, and never wrongly the same).
    pub(crate) fn same_as(&self, other: &Setpoint) -> bool {
        match (self, other) {
            (Setpoint::Ramp(a), Setpoint::Ramp(b)) => a == b,
            (Setpoint::Approach(a), Setpoint::Approach(b)) => a == b,
            (Setpoint::Series(a), Setpoint::Series(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }

    pub fn value(&self, t: f64) -> f64 {
        match self {
            Setpoint::Ramp(r) => r.value(t),
            Setpoint::Approach(a) => a.value(t),
            Setpoint::Series(s) => s.value(t),
        }
    }
}

/// Where the fuel flow comes from during a step.
#[derive(Debug, Clone, PartialEq)]
pub enum FuelCommand {
    Off,
    Fixed(f64),
    /// Open loop: the plant's measured fuel flow drives the model.
    Trace(Arc<Series>),
    /// Closed loop: PI(D-less) on `loop_kind` towards `setpoint`, within `limits`.
    Pid {
        loop_kind: Loop,
        setpoint: Setpoint,
        kp: f64,
        ki: f64,
        aw_tau: f64,
        limits: Arc<FuelLimits>,
    },
}

/// The fuel command's value and its integrator's rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FuelOut {
    pub fuel_kg_s: f64,
    pub integrator_rate: f64,
}

impl FuelCommand {
    /// The next kink of a governing loop's set-point after `t` ([`Setpoint::next_kink`]).
    pub fn next_setpoint_kink(&self, t: f64) -> Option<f64> {
        match self {
            FuelCommand::Pid { setpoint, .. } => setpoint.next_kink(t),
            _ => None,
        }
    }

    /// Whether a governing loop's set-point kinks at `t`.
    pub fn setpoint_kinks_at(&self, t: f64) -> bool {
        match self {
            FuelCommand::Pid { setpoint, .. } => setpoint.kinks_at(t),
            _ => false,
        }
    }

    /// Whether `other` is this command, shared series and limits compared by identity (see
    /// [`Setpoint::same_as`]).
    pub(crate) fn same_as(&self, other: &FuelCommand) -> bool {
        match (self, other) {
            (FuelCommand::Off, FuelCommand::Off) => true,
            (FuelCommand::Fixed(a), FuelCommand::Fixed(b)) => a == b,
            (FuelCommand::Trace(a), FuelCommand::Trace(b)) => Arc::ptr_eq(a, b),
            (
                FuelCommand::Pid {
                    loop_kind,
                    setpoint,
                    kp,
                    ki,
                    aw_tau,
                    limits,
                },
                FuelCommand::Pid {
                    loop_kind: loop_b,
                    setpoint: setpoint_b,
                    kp: kp_b,
                    ki: ki_b,
                    aw_tau: aw_tau_b,
                    limits: limits_b,
                },
            ) => {
                loop_kind == loop_b
                    && setpoint.same_as(setpoint_b)
                    && kp == kp_b
                    && ki == ki_b
                    && aw_tau == aw_tau_b
                    && Arc::ptr_eq(limits, limits_b)
            }
            _ => false,
        }
    }

    /// Builds the PID command for a loop from the control config.
    pub fn pid(
        c: &ControlConfig,
        limits: Arc<FuelLimits>,
        loop_kind: Loop,
        setpoint: Setpoint,
    ) -> FuelCommand {
        let (kp, ki) = match loop_kind {
            Loop::GgSpeed => (c.speed_kp_kg_s_per_rpm, c.speed_ki_kg_s_per_rpm_s),
            Loop::PtSpeed => (c.pt_speed_kp_kg_s_per_rpm, c.pt_speed_ki_kg_s_per_rpm_s),
            Loop::Power => (c.power_kp_kg_s_per_mw, c.power_ki_kg_s_per_mw_s),
        };
        FuelCommand::Pid {
            loop_kind,
            setpoint,
            kp,
            ki,
            aw_tau: c.antiwindup_tau_s,
            limits,
        }
    }

    /// Controller error at this instant (0 for open-loop commands).
    pub fn error(&self, t: f64, m: &Feedback) -> f64 {
        match self {
            FuelCommand::Pid {
                loop_kind,
                setpoint,
                ..
            } => {
                let sp = setpoint.value(t);
                match loop_kind {
                    Loop::GgSpeed => sp - m.n1_rpm,
                    Loop::PtSpeed => sp - m.n2_rpm,
                    Loop::Power => sp - m.power_mw,
                }
            }
            _ => 0.0,
        }
    }

    /// Fuel flow and integrator rate given the integrator value (kg/s).
    pub fn evaluate(&self, t: f64, integ: f64, m: &Feedback) -> FuelOut {
        match self {
            FuelCommand::Off => FuelOut {
                fuel_kg_s: 0.0,
                integrator_rate: 0.0,
            },
            FuelCommand::Fixed(v) => FuelOut {
                fuel_kg_s: *v,
                integrator_rate: 0.0,
            },
            FuelCommand::Trace(tr) => FuelOut {
                fuel_kg_s: tr.value(t).max(0.0),
                integrator_rate: 0.0,
            },
            FuelCommand::Pid {
                kp,
                ki,
                aw_tau,
                limits,
                ..
            } => {
                let e = self.error(t, m);
                let u = kp * e + integ;
                let (lo, hi) = limits.bounds(m.n1_rpm, m.p2_kpa);
                let sat = u.clamp(lo, hi);
                // Back-calculation anti-windup: the integrator is pulled towards the value that
                // the limits let through, so it never winds up while a limit is active.
                FuelOut {
                    fuel_kg_s: sat,
                    integrator_rate: ki * e + (sat - u) / aw_tau,
                }
            }
        }
    }

    /// Integrator value that makes a switch to this command bumpless at fuel `current`.
    pub fn bumpless_integrator(&self, t: f64, current: f64, m: &Feedback) -> f64 {
        match self {
            FuelCommand::Pid { kp, .. } => current - kp * self.error(t, m),
            _ => current,
        }
    }
}

/// What the starter does during a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StarterCommand {
    Off,
    /// Full available torque.
    Full {
        max_torque: f64,
        free_speed: f64,
    },
    /// Full available torque until the GG reaches `cutout_rpm`, then nothing (replays, where the
    /// cut-out is not in the data).
    FullUntil {
        max_torque: f64,
        free_speed: f64,
        cutout_rpm: f64,
    },
    /// Hold a speed (purge) with a proportional torque within the available torque.
    Hold {
        speed_rpm: f64,
        gain: f64,
        max_torque: f64,
        free_speed: f64,
    },
}

impl StarterCommand {
    pub fn full(c: &StarterConfig) -> StarterCommand {
        StarterCommand::Full {
            max_torque: c.max_torque_n_m,
            free_speed: c.free_speed_rpm,
        }
    }

    pub fn hold(c: &StarterConfig, speed_rpm: f64) -> StarterCommand {
        StarterCommand::Hold {
            speed_rpm,
            gain: c.speed_hold_gain_n_m_per_rpm,
            max_torque: c.max_torque_n_m,
            free_speed: c.free_speed_rpm,
        }
    }

    /// Starter torque on the GG shaft at speed `n1`, N·m.
    pub fn torque(&self, n1: f64) -> f64 {
        let avail = |max: f64, free: f64| max * (1.0 - n1 / free).max(0.0);
        match *self {
            StarterCommand::Off => 0.0,
            StarterCommand::Full {
                max_torque,
                free_speed,
            } => avail(max_torque, free_speed),
            StarterCommand::FullUntil {
                max_torque,
                free_speed,
                cutout_rpm,
            } => {
                if n1 < cutout_rpm {
                    avail(max_torque, free_speed)
                } else {
                    0.0
                }
            }
            StarterCommand::Hold {
                speed_rpm,
                gain,
                max_torque,
                free_speed,
            } => (gain * (speed_rpm - n1)).clamp(0.0, avail(max_torque, free_speed)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A set-point's slope jumps at a series' samples and at a ramp's start and end: those are
    /// the kinks the integrator is told of, and nowhere else.
    #[test]
    fn setpoint_kinks_are_the_series_samples_and_the_ramp_ends() {
        let series = Setpoint::Series(Arc::new(Series {
            t_s: vec![10.0, 12.0, 252.0, 372.0],
            value: vec![0.0, 4.0, 4.0, 22.0],
        }));
        assert_eq!(series.next_kink(0.0), Some(10.0));
        assert_eq!(series.next_kink(10.0), Some(12.0));
        assert_eq!(series.next_kink(100.0), Some(252.0));
        assert_eq!(series.next_kink(372.0), None);
        assert!(series.kinks_at(252.0) && !series.kinks_at(252.1) && !series.kinks_at(300.0));
        let ramp = Setpoint::Ramp(Ramp {
            t0: 5.0,
            v0: 1700.0,
            rate: 120.0,
            target: 6600.0,
        });
        let end = 5.0 + 4900.0 / 120.0;
        assert_eq!(ramp.next_kink(0.0), Some(5.0));
        assert_eq!(ramp.next_kink(5.0), Some(end));
        assert_eq!(ramp.next_kink(end), None);
        assert!(ramp.kinks_at(end) && !ramp.kinks_at(20.0));
        assert_eq!(Setpoint::Ramp(Ramp::hold(3600.0)).next_kink(0.0), None);
    }

    #[test]
    fn ramp_and_interp() {
        let r = Ramp {
            t0: 10.0,
            v0: 0.0,
            rate: 2.0,
            target: 10.0,
        };
        assert_eq!(r.value(5.0), 0.0);
        assert_eq!(r.value(12.0), 4.0);
        assert_eq!(r.value(100.0), 10.0);
        assert_eq!(r.end_time(), 15.0);
        let down = Ramp {
            t0: 0.0,
            v0: 10.0,
            rate: 1.0,
            target: 4.0,
        };
        assert_eq!(down.value(3.0), 7.0);
        assert_eq!(down.value(30.0), 4.0);
        assert_eq!(interp(&[0.0, 10.0], &[1.0, 3.0], 5.0), 2.0);
        assert_eq!(interp(&[0.0, 10.0], &[1.0, 3.0], -5.0), 1.0);
        assert_eq!(interp(&[0.0, 10.0], &[1.0, 3.0], 50.0), 3.0);
    }

    #[test]
    fn the_gg_floor_raises_the_lower_limit_below_its_speed_only() {
        let plain = FuelLimits {
            accel_speed_rpm: vec![0.0, 10000.0],
            accel_ratio: vec![1e-3, 1e-3],
            decel_ratio: 1e-4,
            min_fuel: 0.05,
            gg_floor: None,
        };
        let floored = plain.clone().with_gg_floor(GgFloor {
            speed_rpm: 3000.0,
            gain_kg_s_per_rpm: 2e-4,
        });
        // Above the floor's speed the limits are the plain ones.
        assert_eq!(floored.bounds(3500.0, 300.0), plain.bounds(3500.0, 300.0));
        // 1000 rpm below it: 0.2 kg/s, above the flame-holding minimum.
        let (lo, hi) = floored.bounds(2000.0, 300.0);
        assert!((lo - 0.2).abs() < 1e-12, "{lo}");
        assert_eq!(hi, plain.bounds(2000.0, 300.0).1);
        // Never above the acceleration limit.
        assert_eq!(floored.bounds(0.0, 100.0), (0.1, 0.1));
    }

    #[test]
    fn pid_antiwindup_pulls_integrator_to_limit() {
        let limits = Arc::new(FuelLimits {
            accel_speed_rpm: vec![0.0, 10000.0],
            accel_ratio: vec![1e-3, 1e-3],
            decel_ratio: 1e-4,
            min_fuel: 0.05,
            gg_floor: None,
        });
        let cmd = FuelCommand::Pid {
            loop_kind: Loop::GgSpeed,
            setpoint: Setpoint::Ramp(Ramp::hold(9000.0)),
            kp: 1e-4,
            ki: 1e-4,
            aw_tau: 1.0,
            limits,
        };
        let m = Feedback {
            p2_kpa: 1000.0,
            n1_rpm: 5000.0,
            n2_rpm: 0.0,
            power_mw: 0.0,
        };
        // Large error: output saturates at 1 kg/s and the integrator rate is negative when the
        // integrator is above the limit (no wind-up).
        let out = cmd.evaluate(0.0, 2.0, &m);
        assert_eq!(out.fuel_kg_s, 1.0);
        assert!(out.integrator_rate < 0.0);
        let i0 = cmd.bumpless_integrator(0.0, 0.7, &m);
        assert!((cmd.evaluate(0.0, i0, &m).fuel_kg_s - 0.7).abs() < 1e-12);
    }

    #[test]
    fn starter_torque_curve() {
        let s = StarterCommand::Full {
            max_torque: 3000.0,
            free_speed: 6000.0,
        };
        assert_eq!(s.torque(0.0), 3000.0);
        assert_eq!(s.torque(3000.0), 1500.0);
        assert_eq!(s.torque(7000.0), 0.0);
        let h = StarterCommand::Hold {
            speed_rpm: 2300.0,
            gain: 10.0,
            max_torque: 3000.0,
            free_speed: 6000.0,
        };
        assert_eq!(h.torque(2400.0), 0.0);
        assert_eq!(h.torque(2200.0), 1000.0);
    }
}
