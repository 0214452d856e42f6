//! The analysis's verdict: which effect explains the gap, how far it shrinks, whether the
//! baseline stands, and the worst signal left. Must not do I/O.

use super::*;
use crate::diagnosis::periodic;

/// The share of a baseline's oscillation a candidate may leave and still be said to remove it
/// ([`Run::good_explains`]).
const OSCILLATION_LEFT: f64 = 0.5;

impl Run<'_> {
    /// The verdict over the sorted candidates `out`.
    pub(super) fn verdict(
        &self,
        out: &[Candidate],
        aliases: &alias::Aliases,
        spread: f64,
        models: &BTreeMap<String, Vec<Values>>,
    ) -> GapVerdict {
        let base = &self.base;
        if base.fit_quality.residual_verdict == Verdict::Good {
            // Within noise: `none` only when no input instrument can hide behind the health.
            let hidden: Vec<String> = aliases.hidden().into_iter().map(String::from).collect();
            let effect = if hidden.is_empty() { "none" } else { AMBIGUOUS };
            return self.baseline_stands(effect, 0.0, hidden, None);
        }
        let explains = |best: &Candidate| {
            best.shortlisted
                && best.bic_gain > 0.0
                && best.score > spread
                && (best.score >= MIN_SHRINKAGE
                    || (best.fit_quality == Verdict::Good && self.good_explains(best, models)))
                && !best.within_model_error()
        };
        match out.first() {
            Some(best) if explains(best) => {
                // A candidate that explains the residual but needs a health less plausible
                // than the baseline's, where an instrument hidden behind the health would make
                // the baseline's plausible, may be a wrong form of that instrument (see
                // `Aliases::against`): the health is in doubt, and both are named.
                let doubted = aliases.against(&best.health);
                if doubted.is_empty() {
                    GapVerdict {
                        effect: best.effect.clone(),
                        confidence: out
                            .get(1)
                            .filter(|second| second.shortlisted)
                            .map_or(best.score, |second| best.score - second.score.max(0.0))
                            .clamp(0.0, 1.0),
                        shrinkage: best.score,
                        health_before: base.health,
                        health_after: best.health,
                        fit_quality_after: best.fit_quality,
                        aliases: Vec::new(),
                        doubted: None,
                    }
                } else {
                    let restoring = doubted.into_iter().map(String::from).collect();
                    self.baseline_stands(
                        AMBIGUOUS,
                        best.score,
                        restoring,
                        Some(best.effect.clone()),
                    )
                }
            }
            _ => {
                // No candidate explains the residual. If the health is better than new and an
                // input instrument that hides behind it would make it plausible, that
                // instrument is as likely a cause as anything the library lacks (a meter
                // drifting through the start-up is no constant factor, yet mostly one): say
                // the health cannot be trusted and name the instruments, not `unexplained`.
                let restoring: Vec<String> =
                    aliases.restoring().into_iter().map(String::from).collect();
                let effect = if restoring.is_empty() {
                    "unexplained"
                } else {
                    AMBIGUOUS
                };
                let shrinkage = out.first().map_or(0.0, |b| b.score.max(0.0));
                self.baseline_stands(effect, shrinkage, restoring, None)
            }
        }
    }

    /// Whether `best`, whose fit is `good` but whose shrinkage is under [`MIN_SHRINKAGE`],
    /// removes what made the baseline's residual not `good`. A baseline whose residual is within
    /// noise in size (its level and every cell) and was judged `suspect` only for an oscillation
    /// the model lacks is explained only by a candidate that leaves at most half of each
    /// oscillation ([`OSCILLATION_LEFT`]), measured against the candidate's own model: a
    /// candidate's verdict can tip to `good` by the oscillation's amplitude falling just under
    /// the report's threshold ([`crate::diagnosis::periodic`]). On the blind season of
    /// `tests/data/foreign/indep2` (its governor hunts: n1 at 0.093 Hz, 0.3–0.4 σ), three of
    /// twenty analyses named `inlet_temperature` that way with 14–15 % shrinkage, and the
    /// advice set those start-ups aside; the data have no instrument error.
    fn good_explains(&self, best: &Candidate, models: &BTreeMap<String, Vec<Values>>) -> bool {
        let q = &self.base.fit_quality;
        let within_noise = q.normalised_residual <= q.thresholds.good_level
            && q.worst_cell_error <= q.thresholds.suspect_cell;
        if !within_noise || q.periodic.is_empty() {
            return true;
        }
        let Some(model) = models.get(&best.effect).filter(|m| !m.is_empty()) else {
            return false;
        };
        // The samples the baseline compared (those within the adaptation's calibrated range).
        let within = within_calibration(self.engine, self.rec);
        let measured: Vec<Values> = self
            .rec
            .rows()
            .iter()
            .zip(within.iter().chain(std::iter::repeat(&true)))
            .map(|(v, &c)| {
                if c {
                    *v
                } else {
                    [f64::NAN; crate::signals::NSIG]
                }
            })
            .collect();
        let sensors = &self.engine.cfg().sensors;
        let t = self.rec.times();
        // Against the baseline's own model this measure is the amplitude the report gave.
        q.periodic.iter().all(|p| {
            periodic::amplitude_at(t, &measured, model, p.signal, sensors, p.frequency_hz)
                .is_some_and(|left| left <= OSCILLATION_LEFT * p.amplitude_sigma)
        })
    }

    /// A verdict that adopts no effect: the health after, and its fit quality, are the
    /// baseline's (`none`, `unexplained`, `ambiguous`).
    pub(super) fn baseline_stands(
        &self,
        effect: &str,
        shrinkage: f64,
        aliases: Vec<String>,
        doubted: Option<String>,
    ) -> GapVerdict {
        GapVerdict {
            effect: effect.into(),
            confidence: 0.0,
            shrinkage,
            health_before: self.base.health,
            health_after: self.base.health,
            fit_quality_after: self.base.fit_quality.verdict,
            aliases,
            doubted,
        }
    }

    /// The worst signal of the baseline's residual map: measured, the baseline model, and the
    /// verdict's model (when it names one fitted on the whole start-up).
    pub(super) fn worst_signal(
        &self,
        verdict: &GapVerdict,
        models: &BTreeMap<String, Vec<Values>>,
    ) -> Option<SignalTraces> {
        let base = &self.base;
        base.localisation
            .iter()
            .filter(|c| c.norm_error.is_finite())
            .max_by(|a, b| a.norm_error.total_cmp(&b.norm_error))
            .filter(|_| !base.model_values.is_empty())
            .map(|c| {
                let i = c.signal.index();
                let column = |rows: &[Values]| rows.iter().map(|v| v[i]).collect::<Vec<f64>>();
                SignalTraces {
                    signal: c.signal,
                    t_s: self.rec.times().to_vec(),
                    measured: column(self.rec.rows()),
                    before: column(&base.model_values),
                    after: models
                        .get(&verdict.effect)
                        .filter(|m| !m.is_empty())
                        .map(|m| (verdict.effect.clone(), column(m))),
                }
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::sensors::noise_sigma;

    /// A start-up whose only fault is the GG speed oscillating at 0.1 Hz, 0.6 σ: its fit is
    /// `suspect` for that alone. A candidate whose model leaves the oscillation (as every
    /// constant effect does) does not explain it below 30 % shrinkage, whatever its fit quality
    /// says; one whose model carries it does; one without a model on the whole start-up not.
    #[test]
    fn an_oscillation_is_explained_only_by_a_model_that_takes_it_out() {
        let engine = Engine::reference().expect("engine");
        let mut rec =
            crate::diagnosis::bench::synthetic_startup(&engine, &HealthParams::HEALTHY, 3, true)
                .expect("start-up");
        let sensors = engine.cfg().sensors.clone();
        // In the σ the oscillation test reads: the instrument's, floored at 0.1 % of the
        // largest reading (as the objective's).
        let peak = rec
            .series(Signal::N1)
            .into_iter()
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        let ripple = |t: f64, v: f64| {
            let sigma = noise_sigma(&sensors, Signal::N1, v).max(1e-3 * peak);
            0.6 * sigma * (2.0 * std::f64::consts::PI * 0.1 * t).sin()
        };
        let times = rec.times().to_vec();
        for (k, &t) in times.iter().enumerate() {
            if let Some(v) = rec.value(k, Signal::N1) {
                rec.set(k, Signal::N1, v + ripple(t, v)).expect("sets");
            }
        }
        let cfg = DiagnosisConfig::default();
        let base = diagnose_transient(&engine, &rec, &cfg).expect("fits");
        let q = &base.fit_quality;
        assert!(
            q.periodic.iter().any(|p| p.signal == Signal::N1)
                && q.normalised_residual <= q.thresholds.good_level
                && q.worst_cell_error <= q.thresholds.suspect_cell,
            "the premise: suspect for the oscillation alone, {q:?}"
        );
        let leaving = base.model_values.clone();
        let carrying: Vec<Values> = leaving
            .iter()
            .zip(&times)
            .map(|(v, &t)| {
                let mut v = *v;
                v[Signal::N1.index()] += ripple(t, v[Signal::N1.index()]);
                v
            })
            .collect();
        let run = Run {
            engine: &engine,
            rec: &rec,
            holdout: None,
            cfg: &cfg,
            single: cfg.clone(),
            threads: 1,
            scoring: Scoring::BlockedCv,
            k_base: 6,
            base,
        };
        let candidate = Candidate {
            effect: "inlet_temperature".into(),
            params: BTreeMap::new(),
            screen_shrinkage: 0.15,
            shortlisted: true,
            predicted_shrinkage: None,
            train_shrinkage: 0.15,
            heldout_shrinkage: None,
            bic_gain: 100.0,
            score: 0.15,
            health: HealthParams::HEALTHY,
            fit_quality: Verdict::Good,
            normalised_residual: 0.5,
            model_error: None,
        };
        let with = |model: Vec<Values>| BTreeMap::from([("inlet_temperature".to_string(), model)]);
        assert!(!run.good_explains(&candidate, &with(leaving)));
        assert!(run.good_explains(&candidate, &with(carrying)));
        assert!(!run.good_explains(&candidate, &BTreeMap::new()));
    }
}
