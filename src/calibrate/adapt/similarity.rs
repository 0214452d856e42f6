//! Whether the adapted model stays similar: at each baseline point's corrected operating point
//! (its GG and PT speeds over √T1 held), on a day [`SHIFT_K`] colder and one as much warmer,
//! the non-dimensional state (T2/T1, T34/T1, T4/T1, P2/P1, P34/P1, the corrected fuel flow
//! Wf/(δ1·√θ1)) should move no more than the same check moves on the model before the
//! adaptation (real gas is not exactly similar; a map read at corrected speed is).
//!
//! Why: curves fitted to one baseline reproduce it however its loads met its ambients, and a
//! diagnosis at a day that pairs them otherwise relies on similarity to carry the fit over. An
//! adapted model that departs from it fits its baseline within noise and reads a healthy unit
//! on such a day as degraded: on the fourth foreign unit of `tests/foreign_ambient.rs` the HP
//! turbine's curves, functions of its own corrected speed whose temperature (T3) they set, fed
//! back into their argument, and four healthy days read D_GC +1.8…+2.9 points, `poor`. The
//! baseline cannot show it; this check needs no data beyond the points' inputs, so the
//! calibration says so when it happens, and [`super::adapt`] then tries the HP turbine's knots
//! in the GG's corrected speed at the compressor inlet (and, among alternatives fitted to keep
//! the compressor on its map, keeps the one that moves least beyond the model before the
//! adaptation).
//!
//! What it must not do: I/O; change the fit (it measures; `adapt` decides).

use super::super::problem::CalibrationPoint;
use super::before::Before;
use crate::engine::steady::{solve, Demand, SteadyInputs, SteadyPoint};
use crate::engine::Engine;
use serde::Serialize;

/// The ambient shift either way, K.
pub const SHIFT_K: f64 = 25.0;

/// How much more than the model before the adaptation a non-dimensional value may move
/// between the two days (percentage points) before the adapted model is said to depart. Set
/// between two measured cases: the combinator unit of `tests/foreign_engine.rs` moves T34/T1
/// 1.44 % (0.14 % before) at its lowest load and reads healthy days at 258–303 K paired
/// otherwise within 0.5 points, `good`; the unit of `tests/foreign_ambient.rs` moves it 4.72 %
/// (0.33 % before) and reads such days up to 2.9 points off. The other foreign units move
/// 0.1–1.0 points more than before.
pub const DEPARTURE_PCT: f64 = 2.0;

/// The check's outcome.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Similarity {
    /// The largest move of a non-dimensional value on the adapted model, %, with its name and
    /// the relative corrected GG speed of the point where it is.
    pub worst_pct: f64,
    pub worst_of: String,
    pub at_gg_speed: f64,
    /// The largest move of the same value at the same point on the model before the
    /// adaptation, %.
    pub before_pct: f64,
    /// Whether the adapted model departs from similarity (`worst_pct` beyond `before_pct` by
    /// more than [`DEPARTURE_PCT`]).
    pub departs: bool,
    /// Points checked (a point whose shifted days do not both solve is skipped).
    pub points: usize,
}

impl Similarity {
    /// How far the worst value moves beyond its move on the model before the adaptation,
    /// percentage points.
    pub fn excess(&self) -> f64 {
        self.worst_pct - self.before_pct
    }

    /// One line for the report.
    pub fn describe(&self) -> String {
        if self.points == 0 {
            return "similarity not checked (no point solved on both shifted days)".into();
        }
        let moves = format!(
            "{} moves {:.2} % between T1 − {SHIFT_K:.0} K and T1 + {SHIFT_K:.0} K at one \
             corrected operating point (relative GG speed {:.3}), {:.2} % on the model before \
             the adaptation",
            self.worst_of, self.worst_pct, self.at_gg_speed, self.before_pct
        );
        if self.departs {
            format!(
                "similarity: the adapted model departs from it — {moves}: a day whose ambient \
                 meets a load otherwise than on this baseline can read off (a healthy unit as \
                 degraded); record the baseline's loads on days across the seasons and check \
                 with --validate"
            )
        } else {
            format!("similarity kept: {moves}")
        }
    }
}

/// The non-dimensional values compared, each with its name and value (a state) or move (%).
pub type Moves = [(&'static str, f64); 6];

/// The non-dimensional values compared, with their names.
fn state(p: &SteadyPoint) -> Moves {
    let s = &p.stations;
    let theta = s.t1_k / crate::engine::cycle::T_STD_K;
    let delta = s.p1_kpa / crate::engine::cycle::P_STD_KPA;
    [
        ("T2/T1", s.t2_k / s.t1_k),
        ("T34/T1", s.t34_k / s.t1_k),
        ("T4/T1", s.t4_k / s.t1_k),
        ("P2/P1", s.p2_kpa / s.p1_kpa),
        ("P34/P1", s.p34_kpa / s.p1_kpa),
        ("corrected fuel flow", s.fuel_kg_s / (delta * theta.sqrt())),
    ]
}

/// The moves (%) of the non-dimensional values between a day [`SHIFT_K`] colder and one as much
/// warmer than point `p`'s at its corrected speeds on `engine`, or `None` where a solve fails.
pub(super) fn moves(engine: &Engine, p: &CalibrationPoint) -> Option<Moves> {
    let inp = &p.data.inputs;
    let at = p.solved_on(engine).ok()?;
    let day = |dt: f64| -> Option<SteadyPoint> {
        let t = inp.t_amb_k + dt;
        let r = (t / inp.t_amb_k).sqrt();
        let shifted = engine.model_at(&p.health, t, inp.p_amb_kpa);
        let inputs = SteadyInputs {
            t_amb_k: t,
            p_amb_kpa: inp.p_amb_kpa,
            n2_rpm: inp.n2_rpm * r,
            demand: Demand::N1Rpm(at.stations.n1_rpm * r),
        };
        solve(&shifted, &inputs, Some(&at)).ok()
    };
    let (cold, warm) = (state(&day(-SHIFT_K)?), state(&day(SHIFT_K)?));
    let mut out = cold;
    for (o, (c, w)) in out.iter_mut().zip(cold.iter().zip(warm)) {
        o.1 = 100.0 * (w.1 / c.1 - 1.0).abs();
    }
    out.iter().all(|(_, v)| v.is_finite()).then_some(out)
}

/// The check of `adapted` against `before` (the same file before the adaptation, at the same
/// points) at `points`, each with its relative corrected GG speed in `gg_speeds`.
pub(super) fn check(
    before: &Before,
    adapted: &Engine,
    points: &[CalibrationPoint],
    gg_speeds: &[f64],
) -> Similarity {
    let mut out = Similarity::default();
    // The value that moves most beyond what it moves on the model before the adaptation.
    let mut excess = f64::NEG_INFINITY;
    for (i, (p, &speed)) in points.iter().zip(gg_speeds).enumerate() {
        let (Some(a), Some(b)) = (moves(adapted, p), before.moves(i)) else {
            continue;
        };
        out.points += 1;
        for ((name, mv), (_, mv_before)) in a.iter().zip(b) {
            if mv - mv_before > excess {
                excess = mv - mv_before;
                out.worst_pct = *mv;
                out.before_pct = mv_before;
                out.worst_of = name.to_string();
                out.at_gg_speed = speed;
            }
        }
    }
    out.departs = out.points > 0 && out.excess() > DEPARTURE_PCT;
    out
}
